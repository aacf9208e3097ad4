// Forward culling/binning rules and the hand-written backward of the EWA
// projection; tests compare the backward with ceres::Jet of the templates.
#include "gaussian/projection.h"

#include <cmath>

namespace watergs {
namespace {

bool AllFinite(const float* v, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) return false;
  }
  return true;
}

// Inria's getRect: tiles covered by the square of half-size `radius` around
// Inria's pixel position (COLMAP position - 0.5), clamped to the grid.
TileRange TilesOf(double px, double py, double radius, int grid_x, int grid_y) {
  auto tile = [](double v, int grid) {
    const double clamped = std::clamp(v, 0.0, static_cast<double>(grid));
    return static_cast<int>(clamped);
  };
  TileRange r;
  r.x0 = tile((px - radius) / kTileSize, grid_x);
  r.y0 = tile((py - radius) / kTileSize, grid_y);
  r.x1 = tile((px + radius + kTileSize - 1) / kTileSize, grid_x);
  r.y1 = tile((py + radius + kTileSize - 1) / kTileSize, grid_y);
  return r;
}

}  // namespace

ProjectionCamera MakeProjectionCamera(const RenderCamera& camera) {
  ProjectionCamera c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c.R[r * 3 + k] = camera.R(r, k);
    c.t[r] = camera.t[r];
  }
  c.fx = camera.fx, c.fy = camera.fy, c.cx = camera.cx, c.cy = camera.cy;
  c.tan_fovx = 0.5 * camera.width / camera.fx;
  c.tan_fovy = 0.5 * camera.height / camera.fy;
  c.near_plane = camera.near_plane, c.far_plane = camera.far_plane;
  c.width = camera.width, c.height = camera.height;
  const Eigen::Vector3d center = camera.Center();
  for (int k = 0; k < 3; ++k) c.center[k] = center[k];
  return c;
}

bool ProjectForward(const ProjectionCamera& cam, const float* mean,
                    const float* log_scale, const float* quat,
                    ProjectedGaussian* out) {
  // +-inf log-scales are legal (zero / infinite scale): the clamp handles
  // them; NaN anywhere, or a non-finite mean or quaternion, culls.
  if (!AllFinite(mean, 3) || !AllFinite(quat, 4)) return false;
  for (int k = 0; k < 3; ++k) {
    if (std::isnan(log_scale[k])) return false;
  }
  const double m[3] = {mean[0], mean[1], mean[2]};
  const double ls[3] = {log_scale[0], log_scale[1], log_scale[2]};
  const double q[4] = {quat[0], quat[1], quat[2], quat[3]};
  double tcam[3], cov3d[6];
  WorldToCamera(cam, m, tcam);
  if (!(tcam[2] >= cam.near_plane) || !(tcam[2] <= cam.far_plane)) {
    return false;
  }
  Covariance3d(ls, q, cov3d);
  Covariance2d(cam, tcam, cov3d, out->cov2d);
  ProjectMean(cam, tcam, out->mean2d);
  if (!InvertCovariance2d(out->cov2d, out->conic)) return false;
  for (double v : {out->mean2d[0], out->mean2d[1], out->conic[0], out->conic[1],
                   out->conic[2]}) {
    if (!std::isfinite(v)) return false;
  }
  const double* cov = out->cov2d;
  const double det = cov[0] * cov[2] - cov[1] * cov[1];
  const double mid = 0.5 * (cov[0] + cov[2]);
  const double lambda1 = mid + std::sqrt(std::max(0.1, mid * mid - det));
  out->radius = std::min(kMaxRadius, std::ceil(3.0 * std::sqrt(lambda1)));
  if (!(out->radius > 0)) return false;
  const int grid_x = (cam.width + kTileSize - 1) / kTileSize;
  const int grid_y = (cam.height + kTileSize - 1) / kTileSize;
  out->tiles = TilesOf(out->mean2d[0] - 0.5, out->mean2d[1] - 0.5, out->radius,
                       grid_x, grid_y);
  out->depth = tcam[2];
  return !out->tiles.empty();
}

bool MayTouchTiles(const ProjectionCamera& cam, const float* mean,
                   const float* log_scale, const TileRange& range) {
  const double m[3] = {mean[0], mean[1], mean[2]};
  double tcam[3];
  WorldToCamera(cam, m, tcam);
  const double z = tcam[2];
  if (!(z >= cam.near_plane) || !(z <= cam.far_plane)) return false;
  double max_log = kMinLogScale;
  for (int k = 0; k < 3; ++k) {
    if (std::isnan(log_scale[k])) return false;
    max_log = std::max(max_log, ClampLogScale(double(log_scale[k])));
  }
  const double limx = kFrustumClampFactor * cam.tan_fovx;
  const double limy = kFrustumClampFactor * cam.tan_fovy;
  const double u = std::clamp(tcam[0] / z, -limx, limx);
  const double v = std::clamp(tcam[1] / z, -limy, limy);
  // lambda1 <= trace(cov2d) + sqrt(0.1) <= |J|_F^2 s_max^2 + 2 * 0.3 + 0.32.
  const double jf2 =
      (cam.fx * cam.fx * (1 + u * u) + cam.fy * cam.fy * (1 + v * v)) / (z * z);
  const double lambda = jf2 * std::exp(2 * max_log) + 0.92;
  const double radius =
      std::min(kMaxRadius, std::ceil(3.0 * std::sqrt(lambda))) + 1;
  const double px = cam.fx * tcam[0] / z + cam.cx - 0.5;
  const double py = cam.fy * tcam[1] / z + cam.cy - 0.5;
  if (!std::isfinite(px) || !std::isfinite(py)) return true;  // Let it decide.
  return px + radius + kTileSize >= range.x0 * kTileSize &&
         px - radius - kTileSize <= range.x1 * kTileSize &&
         py + radius + kTileSize >= range.y0 * kTileSize &&
         py - radius - kTileSize <= range.y1 * kTileSize;
}

namespace {

// dL/d(cov2d entries A, B, C) from dL/d(conic a, b, c); conic = inverse.
void ConicBackward(const double* cov2d, const double* g, double* g_cov) {
  const double A = cov2d[0], B = cov2d[1], C = cov2d[2];
  const double det = A * C - B * B;
  const double inv2 = 1.0 / (det * det);
  g_cov[0] = (-C * C * g[0] + B * C * g[1] - B * B * g[2]) * inv2;
  g_cov[1] =
      (2 * B * C * g[0] - (det + 2 * B * B) * g[1] + 2 * A * B * g[2]) * inv2;
  g_cov[2] = (-B * B * g[0] + A * B * g[1] - A * A * g[2]) * inv2;
}

// Backward of the Jacobian J (before multiplying by W): dL/dJ (2 x 3,
// row-major, J01 = J10 = 0) to dL/dtcam.
void JacobianBackward(const ProjectionCamera& cam, const double* tcam,
                      const double* gJ, double* g_tcam) {
  const double limx = kFrustumClampFactor * cam.tan_fovx;
  const double limy = kFrustumClampFactor * cam.tan_fovy;
  const double z = tcam[2], inv_z = 1.0 / z;
  const double u_raw = tcam[0] / z, v_raw = tcam[1] / z;
  const bool u_free = u_raw >= -limx && u_raw <= limx;
  const bool v_free = v_raw >= -limy && v_raw <= limy;
  const double u = std::clamp(u_raw, -limx, limx);
  const double v = std::clamp(v_raw, -limy, limy);
  // J00 = fx/z, J11 = fy/z, J02 = -fx u/z, J12 = -fy v/z.
  g_tcam[2] += -cam.fx * inv_z * inv_z * gJ[0] - cam.fy * inv_z * inv_z * gJ[4];
  g_tcam[2] += cam.fx * u * inv_z * inv_z * gJ[2];
  g_tcam[2] += cam.fy * v * inv_z * inv_z * gJ[5];
  const double g_u = -cam.fx * inv_z * gJ[2];
  const double g_v = -cam.fy * inv_z * gJ[5];
  if (u_free) {
    g_tcam[0] += g_u * inv_z;
    g_tcam[2] -= g_u * tcam[0] * inv_z * inv_z;
  }
  if (v_free) {
    g_tcam[1] += g_v * inv_z;
    g_tcam[2] -= g_v * tcam[1] * inv_z * inv_z;
  }
}

// dL/dquat (4, unnormalised) and dL/dlog_scale (3) from dL/dcov3d given as a
// full symmetric 3 x 3 matrix G.
void Covariance3dBackward(const float* log_scale, const float* quat,
                          const double* G, double* g_log_scale,
                          double* g_quat) {
  const double q[4] = {quat[0], quat[1], quat[2], quat[3]};
  double R[9];
  QuatToRotation(q, R);
  double s2[3];
  for (int i = 0; i < 3; ++i) {
    s2[i] = std::exp(2.0 * ClampLogScale(static_cast<double>(log_scale[i])));
  }
  // Sigma = R diag(s2) R^T: dL/dR = 2 G R diag(s2); dL/ds2_i = (R^T G R)_ii.
  double GR[9];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      GR[r * 3 + c] =
          G[r * 3] * R[c] + G[r * 3 + 1] * R[3 + c] + G[r * 3 + 2] * R[6 + c];
    }
  }
  for (int i = 0; i < 3; ++i) {
    const double rgr =
        R[i] * GR[i] + R[3 + i] * GR[3 + i] + R[6 + i] * GR[6 + i];
    const double ls = log_scale[i];
    const bool free = ls >= kMinLogScale && ls <= kMaxLogScale;
    if (free) g_log_scale[i] += 2.0 * s2[i] * rgr;
  }
  double g[9];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g[r * 3 + c] = 2.0 * GR[r * 3 + c] * s2[c];
  }
  const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  if (!(norm2 > 1e-24)) return;  // Identity branch: no dependence on q.
  const double norm = std::sqrt(norm2);
  const double w = q[0] / norm, x = q[1] / norm, y = q[2] / norm,
               z = q[3] / norm;
  const double gn[4] = {
      2 * (-z * g[1] + y * g[2] + z * g[3] - x * g[5] - y * g[6] + x * g[7]),
      2 * (y * g[1] + z * g[2] + y * g[3] - 2 * x * g[4] - w * g[5] + z * g[6] +
           w * g[7] - 2 * x * g[8]),
      2 * (-2 * y * g[0] + x * g[1] + w * g[2] + x * g[3] + z * g[5] -
           w * g[6] + z * g[7] - 2 * y * g[8]),
      2 * (-2 * z * g[0] - w * g[1] + x * g[2] + w * g[3] - 2 * z * g[4] +
           y * g[5] + x * g[6] + y * g[7])};
  const double dot = w * gn[0] + x * gn[1] + y * gn[2] + z * gn[3];
  const double unit[4] = {w, x, y, z};
  for (int k = 0; k < 4; ++k) g_quat[k] += (gn[k] - unit[k] * dot) / norm;
}

}  // namespace

void ProjectBackward(const ProjectionCamera& cam, const float* mean,
                     const float* log_scale, const float* quat,
                     const double* grad_mean2d, const double* grad_conic,
                     double* grad_mean, double* grad_log_scale,
                     double* grad_quat) {
  const double m[3] = {mean[0], mean[1], mean[2]};
  const double ls[3] = {log_scale[0], log_scale[1], log_scale[2]};
  const double q[4] = {quat[0], quat[1], quat[2], quat[3]};
  double tcam[3], cov3d[6], cov2d[3], M[6];
  WorldToCamera(cam, m, tcam);
  Covariance3d(ls, q, cov3d);
  Covariance2d(cam, tcam, cov3d, cov2d);
  ProjectionJacobian(cam, tcam, M);
  double g_cov2d[3];
  ConicBackward(cov2d, grad_conic, g_cov2d);
  // Full symmetric gradient: the off-diagonal B appears twice.
  const double G2[4] = {g_cov2d[0], 0.5 * g_cov2d[1], 0.5 * g_cov2d[1],
                        g_cov2d[2]};
  const double S[9] = {cov3d[0], cov3d[1], cov3d[2], cov3d[1], cov3d[3],
                       cov3d[4], cov3d[2], cov3d[4], cov3d[5]};
  // dL/dSigma = M^T G2 M; dL/dM = 2 G2 M Sigma.
  double G3[9];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      G3[r * 3 + c] = M[r] * (G2[0] * M[c] + G2[1] * M[3 + c]) +
                      M[3 + r] * (G2[2] * M[c] + G2[3] * M[3 + c]);
    }
  }
  double gM[6];
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      double ms = 0;
      for (int k = 0; k < 2; ++k) {
        double mk = 0;
        for (int j = 0; j < 3; ++j) mk += M[k * 3 + j] * S[j * 3 + c];
        ms += G2[r * 2 + k] * mk;
      }
      gM[r * 3 + c] = 2.0 * ms;
    }
  }
  // M = J W: dL/dJ = dL/dM W^T.
  double gJ[6];
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      gJ[r * 3 + c] = gM[r * 3] * cam.R[c * 3] +
                      gM[r * 3 + 1] * cam.R[c * 3 + 1] +
                      gM[r * 3 + 2] * cam.R[c * 3 + 2];
    }
  }
  double g_tcam[3] = {0, 0, 0};
  JacobianBackward(cam, tcam, gJ, g_tcam);
  const double inv_z = 1.0 / tcam[2];
  g_tcam[0] += cam.fx * inv_z * grad_mean2d[0];
  g_tcam[1] += cam.fy * inv_z * grad_mean2d[1];
  g_tcam[2] -=
      (cam.fx * tcam[0] * grad_mean2d[0] + cam.fy * tcam[1] * grad_mean2d[1]) *
      inv_z * inv_z;
  for (int k = 0; k < 3; ++k) {
    grad_mean[k] += cam.R[k] * g_tcam[0] + cam.R[3 + k] * g_tcam[1] +
                    cam.R[6 + k] * g_tcam[2];
  }
  Covariance3dBackward(log_scale, quat, G3, grad_log_scale, grad_quat);
}

void ComputeScreenRadii(const GaussianModel& model, const RenderCamera& camera,
                        const std::vector<uint8_t>& visible,
                        std::vector<float>* radii) {
  const ProjectionCamera cam = MakeProjectionCamera(camera);
  const int64_t n = static_cast<int64_t>(model.size());
  radii->assign(n, 0.f);
#pragma omp parallel for schedule(static) if (n > 20000)
  for (int64_t i = 0; i < n; ++i) {
    if (!visible[i]) continue;
    ProjectedGaussian p;
    if (ProjectForward(cam, &model.means[3 * i], &model.log_scales[3 * i],
                       &model.quats[4 * i], &p)) {
      (*radii)[i] = static_cast<float>(p.radius);
    }
  }
}

}  // namespace watergs
