// CUDA twin of the per-Gaussian stages: EWA projection and culling
// (projection.cc), SH colour and its backward (sh.h, sh.cc), and the
// per-Gaussian parts of cpu_rasterizer.cc (ProjectModel's shading and alpha
// support, GaussianBackward). One thread per Gaussian, in double like the
// CPU code, with the same formulas in the same order so that a parity
// mismatch points at one function.
#include <cuda_runtime.h>

#include <cstdint>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/raster_kernels.h"

namespace watergs::cuda_raster {
namespace {

// Constants of projection.h and sh.h (device code reads scalars only).
constexpr double kMinLogScale = -30.0;
constexpr double kMaxLogScale = 20.0;
constexpr double kCovDilation = 0.3;
constexpr double kFrustumClampFactor = 1.3;
constexpr double kMaxRadius = 1.0e6;
constexpr double kShC0 = 0.28209479177387814;
constexpr double kShC1 = 0.4886025119029199;
constexpr double kShC2a = 1.0925484305920792, kShC2b = -1.0925484305920792,
                 kShC2c = 0.31539156525252005, kShC2d = -1.0925484305920792,
                 kShC2e = 0.5462742152960396;
constexpr double kShC3a = -0.5900435899266435, kShC3b = 2.890611442640554,
                 kShC3c = -0.4570457994644658, kShC3d = 0.3731763325901154,
                 kShC3e = -0.4570457994644658, kShC3f = 1.445305721320277,
                 kShC3g = -0.5900435899266435;
constexpr int kThreads = 256;

// ---------------------------------------------------------------------------
// Forward math (projection.h templates, T = double).

__device__ double ClampLogScale(double log_scale) {
  if (log_scale < kMinLogScale) return kMinLogScale;
  if (log_scale > kMaxLogScale) return kMaxLogScale;
  return log_scale;
}

__device__ void QuatToRotation(const double* q, double* R) {
  const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  double w = 1, x = 0, y = 0, z = 0;
  if (norm2 > 1e-24) {
    const double inv = 1.0 / sqrt(norm2);
    w = q[0] * inv, x = q[1] * inv, y = q[2] * inv, z = q[3] * inv;
  }
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
}

// cov = (xx, xy, xz, yy, yz, zz) of R diag(s^2) R^T.
__device__ void Covariance3d(const double* log_scale, const double* quat,
                             double* cov) {
  double R[9], s2[3];
  QuatToRotation(quat, R);
  for (int i = 0; i < 3; ++i) s2[i] = exp(2 * ClampLogScale(log_scale[i]));
  auto entry = [&](int r, int c) {
    return R[r * 3 + 0] * R[c * 3 + 0] * s2[0] +
           R[r * 3 + 1] * R[c * 3 + 1] * s2[1] +
           R[r * 3 + 2] * R[c * 3 + 2] * s2[2];
  };
  cov[0] = entry(0, 0), cov[1] = entry(0, 1), cov[2] = entry(0, 2);
  cov[3] = entry(1, 1), cov[4] = entry(1, 2), cov[5] = entry(2, 2);
}

__device__ void WorldToCamera(const DeviceCamera& cam, const double* mean,
                              double* tcam) {
  for (int r = 0; r < 3; ++r) {
    tcam[r] = cam.R[r * 3] * mean[0] + cam.R[r * 3 + 1] * mean[1] +
              cam.R[r * 3 + 2] * mean[2] + cam.t[r];
  }
}

__device__ void ProjectMean(const DeviceCamera& cam, const double* tcam,
                            double* mean2d) {
  mean2d[0] = cam.fx * tcam[0] / tcam[2] + cam.cx;
  mean2d[1] = cam.fy * tcam[1] / tcam[2] + cam.cy;
}

// J W (2 x 3, row-major) with Inria's clamp of x/z, y/z.
__device__ void ProjectionJacobian(const DeviceCamera& cam, const double* tcam,
                                   double* JW) {
  const double limx = kFrustumClampFactor * cam.tan_fovx;
  const double limy = kFrustumClampFactor * cam.tan_fovy;
  double u = tcam[0] / tcam[2], v = tcam[1] / tcam[2];
  if (u < -limx) u = -limx;
  if (u > limx) u = limx;
  if (v < -limy) v = -limy;
  if (v > limy) v = limy;
  const double inv_z = 1 / tcam[2];
  const double J[6] = {cam.fx * inv_z,      0,
                       -cam.fx * u * inv_z, 0,
                       cam.fy * inv_z,      -cam.fy * v * inv_z};
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      JW[r * 3 + c] = J[r * 3] * cam.R[c] + J[r * 3 + 1] * cam.R[3 + c] +
                      J[r * 3 + 2] * cam.R[6 + c];
    }
  }
}

// (JW) cov3d (JW)^T + 0.3 I as (xx, xy, yy).
__device__ void Covariance2d(const DeviceCamera& cam, const double* tcam,
                             const double* cov3d, double* cov2d) {
  double M[6], MS[6];
  ProjectionJacobian(cam, tcam, M);
  const double S[9] = {cov3d[0], cov3d[1], cov3d[2], cov3d[1], cov3d[3],
                       cov3d[4], cov3d[2], cov3d[4], cov3d[5]};
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      MS[r * 3 + c] =
          M[r * 3] * S[c] + M[r * 3 + 1] * S[3 + c] + M[r * 3 + 2] * S[6 + c];
    }
  }
  auto entry = [&](int r, int c) {
    return MS[r * 3] * M[c * 3] + MS[r * 3 + 1] * M[c * 3 + 1] +
           MS[r * 3 + 2] * M[c * 3 + 2];
  };
  cov2d[0] = entry(0, 0) + kCovDilation;
  cov2d[1] = entry(0, 1);
  cov2d[2] = entry(1, 1) + kCovDilation;
}

__device__ bool InvertCovariance2d(const double* cov2d, double* conic) {
  const double det = cov2d[0] * cov2d[2] - cov2d[1] * cov2d[1];
  if (!(det > 0)) return false;
  const double inv = 1 / det;
  conic[0] = cov2d[2] * inv;
  conic[1] = -cov2d[1] * inv;
  conic[2] = cov2d[0] * inv;
  return true;
}

__device__ TileRect Intersect(const TileRect& a, const TileRect& b) {
  TileRect r;
  r.x0 = max(a.x0, b.x0);
  r.y0 = max(a.y0, b.y0);
  r.x1 = max(r.x0, min(a.x1, b.x1));
  r.y1 = max(r.y0, min(a.y1, b.y1));
  return r;
}

__device__ bool Empty(const TileRect& r) {
  return r.x1 <= r.x0 || r.y1 <= r.y0;
}

// ProjectedGaussian of projection.h.
struct Projected {
  double mean2d[2], conic[3], cov2d[3], depth, radius;
  TileRect tiles;
};

// Inria's getRect (TilesOf in projection.cc).
__device__ TileRect TilesOf(double px, double py, double radius, int grid_x,
                            int grid_y) {
  auto tile = [](double v, int grid) {
    return static_cast<int>(fmin(fmax(v, 0.0), static_cast<double>(grid)));
  };
  TileRect r;
  r.x0 = tile((px - radius) / kTile, grid_x);
  r.y0 = tile((py - radius) / kTile, grid_y);
  r.x1 = tile((px + radius + kTile - 1) / kTile, grid_x);
  r.y1 = tile((py + radius + kTile - 1) / kTile, grid_y);
  return r;
}

// ProjectForward of projection.cc: false if culled.
__device__ bool ProjectForward(const DeviceCamera& cam, const float* mean,
                               const float* log_scale, const float* quat,
                               Projected* out) {
  for (int k = 0; k < 3; ++k) {
    if (!isfinite(mean[k]) || isnan(log_scale[k])) return false;
  }
  for (int k = 0; k < 4; ++k) {
    if (!isfinite(quat[k])) return false;
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
  if (!isfinite(out->mean2d[0]) || !isfinite(out->mean2d[1]) ||
      !isfinite(out->conic[0]) || !isfinite(out->conic[1]) ||
      !isfinite(out->conic[2])) {
    return false;
  }
  const double* cov = out->cov2d;
  const double det = cov[0] * cov[2] - cov[1] * cov[1];
  const double mid = 0.5 * (cov[0] + cov[2]);
  const double lambda1 = mid + sqrt(fmax(0.1, mid * mid - det));
  out->radius = fmin(kMaxRadius, ceil(3.0 * sqrt(lambda1)));
  if (!(out->radius > 0)) return false;
  const int grid_x = (cam.width + kTile - 1) / kTile;
  const int grid_y = (cam.height + kTile - 1) / kTile;
  out->tiles = TilesOf(out->mean2d[0] - 0.5, out->mean2d[1] - 0.5, out->radius,
                       grid_x, grid_y);
  out->depth = tcam[2];
  return !Empty(out->tiles);
}

// AlphaSupport of cpu_rasterizer.cc: rows and tiles where alpha can reach
// 1/255; false if it never can.
__device__ bool AlphaSupport(const Projected& p, float opacity, DeviceSplat* s,
                             TileRect* tiles) {
  const double level = log(255.0 * static_cast<double>(opacity));
  if (!(level > 0)) return false;
  auto half = [&](double var) {
    return fmin(kMaxRadius, sqrt(2.0 * level * var) * (1 + 1e-3) + 0.05);
  };
  const double hx = half(p.cov2d[0]), hy = half(p.cov2d[2]);
  const double y_lo = ceil(p.mean2d[1] - hy - 0.5);
  const double y_hi = floor(p.mean2d[1] + hy - 0.5);
  const double x_lo = ceil(p.mean2d[0] - hx - 0.5);
  const double x_hi = floor(p.mean2d[0] + hx - 0.5);
  if (y_hi < y_lo || x_hi < x_lo) return false;
  auto clamp_int = [](double v) {
    return static_cast<int>(fmin(fmax(v, -1.0e8), 1.0e8));
  };
  s->row_min = clamp_int(y_lo);
  s->row_max = clamp_int(y_hi);
  const double a = p.conic[0], b = p.conic[1];
  const double shear = -b / a, reach = 2.0 * level / a;
  const double narrowing = 1.0 / (a * p.cov2d[2]);
  const bool usable =
      isfinite(shear) && isfinite(reach) && isfinite(narrowing) && reach < 1e30;
  s->shear = usable ? static_cast<float>(shear) : 0.f;
  s->reach = usable ? static_cast<float>(reach) * 1.001f : 1e30f;
  s->narrowing = usable ? static_cast<float>(narrowing) * 0.999f : 0.f;
  auto tile = [](int v) {
    return v >= 0 ? v / kTile : -((-v + kTile - 1) / kTile);
  };
  tiles->x0 = tile(clamp_int(x_lo));
  tiles->x1 = tile(clamp_int(x_hi)) + 1;
  tiles->y0 = tile(s->row_min);
  tiles->y1 = tile(s->row_max) + 1;
  return true;
}

// The NumShCoeffs(degree) basis values at unit direction (x, y, z).
__device__ void ShBasis(int degree, double x, double y, double z,
                        double* basis) {
  basis[0] = kShC0;
  if (degree < 1) return;
  basis[1] = -kShC1 * y;
  basis[2] = kShC1 * z;
  basis[3] = -kShC1 * x;
  if (degree < 2) return;
  const double xx = x * x, yy = y * y, zz = z * z;
  basis[4] = kShC2a * x * y;
  basis[5] = kShC2b * y * z;
  basis[6] = kShC2c * (2 * zz - xx - yy);
  basis[7] = kShC2d * x * z;
  basis[8] = kShC2e * (xx - yy);
  if (degree < 3) return;
  basis[9] = kShC3a * y * (3 * xx - yy);
  basis[10] = kShC3b * x * y * z;
  basis[11] = kShC3c * y * (4 * zz - xx - yy);
  basis[12] = kShC3d * z * (2 * zz - 3 * xx - 3 * yy);
  basis[13] = kShC3e * x * (4 * zz - xx - yy);
  basis[14] = kShC3f * z * (xx - yy);
  basis[15] = kShC3g * x * (xx - 3 * yy);
}

// dir / |dir| (UnitDirection of sh.cc); false (and +z) for a zero direction.
__device__ bool UnitDirection(const double* dir, double* norm, double* x,
                              double* y, double* z) {
  *norm = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  const bool ok = *norm > 1e-30;
  *x = ok ? dir[0] / *norm : 0;
  *y = ok ? dir[1] / *norm : 0;
  *z = ok ? dir[2] / *norm : 1;
  return ok;
}

// ShColorUnclamped of sh.h (T = double, C = float).
__device__ void ShColorUnclamped(int degree, const float* dc, const float* rest,
                                 const double* dir, double* rgb) {
  double norm, x, y, z, basis[16];
  UnitDirection(dir, &norm, &x, &y, &z);
  ShBasis(degree, x, y, z, basis);
  const int count = (degree + 1) * (degree + 1);
  for (int ch = 0; ch < 3; ++ch) {
    double sum = basis[0] * static_cast<double>(dc[ch]);
    for (int k = 1; k < count; ++k) {
      sum += basis[k] * static_cast<double>(rest[(k - 1) * 3 + ch]);
    }
    rgb[ch] = sum + 0.5;
  }
}

__global__ void ProjectKernel(DeviceModel model, DeviceCamera cam, int degree,
                              TileRect render_tiles, ProjectionOutputs out) {
  // 64-bit: 4 * i overflows int from 2^29 Gaussians on.
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= model.count) return;
  out.visible[i] = 0;
  out.tile_counts[i] = 0;
  out.clamped[i] = 0;
  out.depth[i] = 0.f;
  out.tiles[i] = TileRect{0, 0, 0, 0};
  if (out.radii) out.radii[i] = 0.f;
  Projected p;
  if (!ProjectForward(cam, &model.means[3 * i], &model.log_scales[3 * i],
                      &model.quats[4 * i], &p)) {
    return;
  }
  if (Empty(Intersect(p.tiles, render_tiles))) return;
  out.visible[i] = 1;
  if (out.radii) out.radii[i] = static_cast<float>(p.radius);
  const float opacity = static_cast<float>(
      1.0 / (1.0 + exp(-static_cast<double>(model.opacity_logits[i]))));
  DeviceSplat s{};
  s.mean_x = static_cast<float>(p.mean2d[0]);
  s.mean_y = static_cast<float>(p.mean2d[1]);
  s.conic_a = static_cast<float>(p.conic[0]);
  s.conic_b = static_cast<float>(p.conic[1]);
  s.conic_c = static_cast<float>(p.conic[2]);
  s.opacity = opacity;
  TileRect support;
  if (!AlphaSupport(p, opacity, &s, &support)) return;
  const TileRect tiles = Intersect(Intersect(p.tiles, render_tiles), support);
  if (Empty(tiles)) return;
  // ShadeSplat: clamped colour and its clamp bits.
  const float* m = &model.means[3 * i];
  const double dir[3] = {m[0] - cam.center[0], m[1] - cam.center[1],
                         m[2] - cam.center[2]};
  double rgb[3];
  ShColorUnclamped(degree, &model.sh_dc[3 * i],
                   model.sh_rest + static_cast<size_t>(i) * model.rest_stride,
                   dir, rgb);
  uint8_t clamped = 0;
  for (int ch = 0; ch < 3; ++ch) {
    if (!(rgb[ch] >= 0)) clamped |= uint8_t(1u << ch);
    s.color[ch] = clamped & (1u << ch) ? 0.f : static_cast<float>(rgb[ch]);
  }
  out.splats[i] = s;
  out.tiles[i] = tiles;
  out.depth[i] = static_cast<float>(p.depth);
  out.clamped[i] = clamped;
  out.tile_counts[i] = static_cast<uint64_t>(tiles.x1 - tiles.x0) *
                       static_cast<uint64_t>(tiles.y1 - tiles.y0);
}

// ---------------------------------------------------------------------------
// Backward math (projection.cc, sh.cc).

// ShBasisGradient of sh.cc.
__device__ void ShBasisGradient(int degree, double x, double y, double z,
                                double* d_dx, double* d_dy, double* d_dz) {
  const int count = (degree + 1) * (degree + 1);
  for (int k = 0; k < count; ++k) d_dx[k] = d_dy[k] = d_dz[k] = 0;
  if (degree < 1) return;
  d_dy[1] = -kShC1;
  d_dz[2] = kShC1;
  d_dx[3] = -kShC1;
  if (degree < 2) return;
  const double xx = x * x, yy = y * y, zz = z * z;
  d_dx[4] = kShC2a * y, d_dy[4] = kShC2a * x;
  d_dy[5] = kShC2b * z, d_dz[5] = kShC2b * y;
  d_dx[6] = -2 * kShC2c * x, d_dy[6] = -2 * kShC2c * y;
  d_dz[6] = 4 * kShC2c * z;
  d_dx[7] = kShC2d * z, d_dz[7] = kShC2d * x;
  d_dx[8] = 2 * kShC2e * x, d_dy[8] = -2 * kShC2e * y;
  if (degree < 3) return;
  d_dx[9] = 6 * kShC3a * x * y, d_dy[9] = kShC3a * (3 * xx - 3 * yy);
  d_dx[10] = kShC3b * y * z, d_dy[10] = kShC3b * x * z;
  d_dz[10] = kShC3b * x * y;
  d_dx[11] = -2 * kShC3c * x * y;
  d_dy[11] = kShC3c * (4 * zz - xx - 3 * yy);
  d_dz[11] = 8 * kShC3c * y * z;
  d_dx[12] = -6 * kShC3d * x * z, d_dy[12] = -6 * kShC3d * y * z;
  d_dz[12] = kShC3d * (6 * zz - 3 * xx - 3 * yy);
  d_dx[13] = kShC3e * (4 * zz - 3 * xx - yy);
  d_dy[13] = -2 * kShC3e * x * y, d_dz[13] = 8 * kShC3e * x * z;
  d_dx[14] = 2 * kShC3f * x * z, d_dy[14] = -2 * kShC3f * y * z;
  d_dz[14] = kShC3f * (xx - yy);
  d_dx[15] = kShC3g * (3 * xx - 3 * yy), d_dy[15] = -6 * kShC3g * x * y;
}

// ShColorBackward of sh.cc; grad_dc / grad_rest (zeroed) may be null (compact
// SH gradients: only the direction gradient is wanted).
__device__ void ShColorBackward(int degree, const float* rest,
                                const double* dir, const double* grad_rgb,
                                float* grad_dc, float* grad_rest,
                                double* grad_dir) {
  double norm, x, y, z;
  const bool degenerate = !UnitDirection(dir, &norm, &x, &y, &z);
  double basis[16], d_dx[16], d_dy[16], d_dz[16];
  ShBasis(degree, x, y, z, basis);
  ShBasisGradient(degree, x, y, z, d_dx, d_dy, d_dz);
  const int count = (degree + 1) * (degree + 1);
  const double g0 = grad_rgb[0], g1 = grad_rgb[1], g2 = grad_rgb[2];
  if (grad_dc != nullptr) {
    grad_dc[0] = static_cast<float>(basis[0] * g0);
    grad_dc[1] = static_cast<float>(basis[0] * g1);
    grad_dc[2] = static_cast<float>(basis[0] * g2);
  }
  double grad_unit[3] = {0, 0, 0};
  for (int k = 1; k < count; ++k) {
    const float* c = rest + (k - 1) * 3;
    if (grad_rest != nullptr) {
      float* gc = grad_rest + (k - 1) * 3;
      gc[0] = static_cast<float>(basis[k] * g0);
      gc[1] = static_cast<float>(basis[k] * g1);
      gc[2] = static_cast<float>(basis[k] * g2);
    }
    const double weight = c[0] * g0 + c[1] * g1 + c[2] * g2;
    grad_unit[0] += d_dx[k] * weight;
    grad_unit[1] += d_dy[k] * weight;
    grad_unit[2] += d_dz[k] * weight;
  }
  if (degenerate || degree == 0) return;
  const double dot = x * grad_unit[0] + y * grad_unit[1] + z * grad_unit[2];
  grad_dir[0] += (grad_unit[0] - x * dot) / norm;
  grad_dir[1] += (grad_unit[1] - y * dot) / norm;
  grad_dir[2] += (grad_unit[2] - z * dot) / norm;
}

// dL/d(cov2d A, B, C) from dL/d(conic a, b, c).
__device__ void ConicBackward(const double* cov2d, const double* g,
                              double* g_cov) {
  const double A = cov2d[0], B = cov2d[1], C = cov2d[2];
  const double det = A * C - B * B;
  const double inv2 = 1.0 / (det * det);
  g_cov[0] = (-C * C * g[0] + B * C * g[1] - B * B * g[2]) * inv2;
  g_cov[1] =
      (2 * B * C * g[0] - (det + 2 * B * B) * g[1] + 2 * A * B * g[2]) * inv2;
  g_cov[2] = (-B * B * g[0] + A * B * g[1] - A * A * g[2]) * inv2;
}

// dL/dJ (2 x 3) to dL/dtcam, respecting the x/z, y/z clamp.
__device__ void JacobianBackward(const DeviceCamera& cam, const double* tcam,
                                 const double* gJ, double* g_tcam) {
  const double limx = kFrustumClampFactor * cam.tan_fovx;
  const double limy = kFrustumClampFactor * cam.tan_fovy;
  const double z = tcam[2], inv_z = 1.0 / z;
  const double u_raw = tcam[0] / z, v_raw = tcam[1] / z;
  const bool u_free = u_raw >= -limx && u_raw <= limx;
  const bool v_free = v_raw >= -limy && v_raw <= limy;
  const double u = fmin(fmax(u_raw, -limx), limx);
  const double v = fmin(fmax(v_raw, -limy), limy);
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

// dL/dquat (unnormalised) and dL/dlog_scale from the symmetric dL/dcov3d G.
__device__ void Covariance3dBackward(const float* log_scale, const float* quat,
                                     const double* G, double* g_log_scale,
                                     double* g_quat) {
  const double q[4] = {quat[0], quat[1], quat[2], quat[3]};
  double R[9], s2[3], GR[9], g[9];
  QuatToRotation(q, R);
  for (int i = 0; i < 3; ++i) {
    s2[i] = exp(2.0 * ClampLogScale(static_cast<double>(log_scale[i])));
  }
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
    if (ls >= kMinLogScale && ls <= kMaxLogScale) {
      g_log_scale[i] += 2.0 * s2[i] * rgr;
    }
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g[r * 3 + c] = 2.0 * GR[r * 3 + c] * s2[c];
  }
  const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  if (!(norm2 > 1e-24)) return;  // Identity branch: no dependence on q.
  const double norm = sqrt(norm2);
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

// ProjectBackward of projection.cc.
__device__ void ProjectBackward(const DeviceCamera& cam, const float* mean,
                                const float* log_scale, const float* quat,
                                const double* grad_mean2d,
                                const double* grad_conic, double* grad_mean,
                                double* grad_log_scale, double* grad_quat) {
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
  const double G2[4] = {g_cov2d[0], 0.5 * g_cov2d[1], 0.5 * g_cov2d[1],
                        g_cov2d[2]};
  const double S[9] = {cov3d[0], cov3d[1], cov3d[2], cov3d[1], cov3d[3],
                       cov3d[4], cov3d[2], cov3d[4], cov3d[5]};
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

// GaussianBackward of cpu_rasterizer.cc: every gradient of Gaussian i.
__global__ void GaussianBackwardKernel(
    DeviceModel model, DeviceCamera cam, int degree, int frame_width,
    int frame_height, const uint64_t* tile_counts, const uint8_t* clamped,
    const DeviceSplatGrad* splat_grads, GradientOutputs out) {
  // 64-bit: 4 * i overflows int from 2^29 Gaussians on.
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= model.count) return;
  const int stride = model.rest_stride;
  float* grad_dc = out.compact ? nullptr : &out.sh_dc[3 * i];
  float* grad_rest =
      out.compact ? nullptr : out.sh_rest + static_cast<size_t>(i) * stride;
  if (out.compact) {
    for (int d = 0; d < 3; ++d) {
      out.sh_color_grad[3 * i + d] = 0.f;
      out.sh_view_dir[3 * i + d] = 0.f;
    }
  } else {
    for (int k = 0; k < stride; ++k) grad_rest[k] = 0.f;
    for (int d = 0; d < 3; ++d) grad_dc[d] = 0.f;
  }
  double grad_mean[3] = {0, 0, 0}, grad_ls[3] = {0, 0, 0};
  double grad_q[4] = {0, 0, 0, 0}, grad_logit = 0;
  double grad_mean2d[2] = {0, 0};
  if (tile_counts[i] > 0) {
    const DeviceSplatGrad g = splat_grads[i];
    const float* mean = &model.means[3 * i];
    double grad_rgb[3];
    for (int ch = 0; ch < 3; ++ch) {
      grad_rgb[ch] = clamped[i] & (1u << ch) ? 0.0 : g.color[ch];
    }
    const double dir[3] = {mean[0] - cam.center[0], mean[1] - cam.center[1],
                           mean[2] - cam.center[2]};
    ShColorBackward(degree, model.sh_rest + static_cast<size_t>(i) * stride,
                    dir, grad_rgb, grad_dc, grad_rest, grad_mean);
    if (out.compact) {
      for (int d = 0; d < 3; ++d) {
        out.sh_color_grad[3 * i + d] = static_cast<float>(grad_rgb[d]);
        out.sh_view_dir[3 * i + d] = static_cast<float>(dir[d]);
      }
    }
    const double s =
        1.0 / (1.0 + exp(-static_cast<double>(model.opacity_logits[i])));
    grad_logit = g.opacity * s * (1 - s);
    grad_mean2d[0] = g.mean_x, grad_mean2d[1] = g.mean_y;
    const double grad_conic[3] = {g.conic_a, g.conic_b, g.conic_c};
    ProjectBackward(cam, mean, &model.log_scales[3 * i], &model.quats[4 * i],
                    grad_mean2d, grad_conic, grad_mean, grad_ls, grad_q);
  }
  for (int d = 0; d < 3; ++d) {
    out.means[3 * i + d] = static_cast<float>(grad_mean[d]);
    out.log_scales[3 * i + d] = static_cast<float>(grad_ls[d]);
  }
  for (int d = 0; d < 4; ++d) {
    out.quats[4 * i + d] = static_cast<float>(grad_q[d]);
  }
  out.opacity_logits[i] = static_cast<float>(grad_logit);
  const double gx = grad_mean2d[0], gy = grad_mean2d[1];
  const double half_w = 0.5 * frame_width, half_h = 0.5 * frame_height;
  out.mean2d_grad_norm[i] = static_cast<float>(sqrt(gx * gx + gy * gy));
  out.mean2d_grad_norm_ndc[i] = static_cast<float>(
      sqrt(gx * gx * half_w * half_w + gy * gy * half_h * half_h));
}

unsigned Blocks(int n) {
  return static_cast<unsigned>((static_cast<int64_t>(n) + kThreads - 1) /
                               kThreads);
}

}  // namespace

void LaunchProject(const DeviceModel& model, const DeviceCamera& camera,
                   int active_sh_degree, TileRect render_tiles,
                   ProjectionOutputs out) {
  if (model.count <= 0) return;
  ProjectKernel<<<Blocks(model.count), kThreads>>>(
      model, camera, active_sh_degree, render_tiles, out);
  WATERGS_CUDA_CHECK_LAUNCH();
}

void LaunchGaussianBackward(const DeviceModel& model,
                            const DeviceCamera& camera, int active_sh_degree,
                            int frame_width, int frame_height,
                            const uint64_t* tile_counts, const uint8_t* clamped,
                            const DeviceSplatGrad* splat_grads,
                            GradientOutputs out) {
  if (model.count <= 0) return;
  GaussianBackwardKernel<<<Blocks(model.count), kThreads>>>(
      model, camera, active_sh_degree, frame_width, frame_height, tile_counts,
      clamped, splat_grads, out);
  WATERGS_CUDA_CHECK_LAUNCH();
}

}  // namespace watergs::cuda_raster
