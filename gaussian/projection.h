// Per-Gaussian EWA projection (Inria 3DGS math): quaternion + log-scale to a
// 3D covariance, world to camera, the perspective Jacobian (with Inria's
// 1.3 x tan(half-FOV) clamp of x/z and y/z), 2D covariance + 0.3 px
// dilation, its inverse (the conic), 3-sigma radius and culling. The math is
// written once as templates so tests can evaluate it with ceres::Jet; the
// hand-written backward lives in projection.cc.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

// Side of a square screen tile in pixels.
inline constexpr int kTileSize = 16;
// Log-scales are clamped to this range before exp (zero gradient outside),
// so zero, denormal and huge scales stay finite in every intermediate.
inline constexpr double kMinLogScale = -30.0;
inline constexpr double kMaxLogScale = 20.0;
// Low-pass dilation added to the 2D covariance diagonal, in pixels^2.
inline constexpr double kCovDilation = 0.3;
// Inria clamps x/z and y/z to this multiple of tan(half-FOV).
inline constexpr double kFrustumClampFactor = 1.3;
// Radii are capped here (pixels) so huge Gaussians stay representable.
inline constexpr double kMaxRadius = 1.0e6;

// Camera quantities the projection needs, all in double.
struct ProjectionCamera {
  // World-to-camera rotation (row-major) and translation.
  double R[9];
  double t[3];
  // Pinhole intrinsics in pixels (COLMAP convention, centre at +0.5).
  double fx, fy, cx, cy;
  // tan of the half field of view: 0.5 * width / fx, 0.5 * height / fy.
  double tan_fovx, tan_fovy;
  // Depth culling range.
  double near_plane, far_plane;
  // Full frame size in pixels.
  int width, height;
  // Camera centre in world coordinates (for SH view directions).
  double center[3];
};
ProjectionCamera MakeProjectionCamera(const RenderCamera& camera);

// Rotation matrix (row-major) of quaternion q = (w, x, y, z) after
// normalisation; a (near) zero quaternion gives the identity.
template <typename T>
void QuatToRotation(const T* q, T* R) {
  using std::sqrt;
  const T norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  T w(1), x(0), y(0), z(0);
  if (norm2 > T(1e-24)) {
    const T inv = T(1) / sqrt(norm2);
    w = q[0] * inv, x = q[1] * inv, y = q[2] * inv, z = q[3] * inv;
  }
  R[0] = T(1) - T(2) * (y * y + z * z);
  R[1] = T(2) * (x * y - w * z);
  R[2] = T(2) * (x * z + w * y);
  R[3] = T(2) * (x * y + w * z);
  R[4] = T(1) - T(2) * (x * x + z * z);
  R[5] = T(2) * (y * z - w * x);
  R[6] = T(2) * (x * z - w * y);
  R[7] = T(2) * (y * z + w * x);
  R[8] = T(1) - T(2) * (x * x + y * y);
}

// Log-scale clamped to [kMinLogScale, kMaxLogScale].
template <typename T>
T ClampLogScale(const T& log_scale) {
  if (log_scale < T(kMinLogScale)) return T(kMinLogScale);
  if (log_scale > T(kMaxLogScale)) return T(kMaxLogScale);
  return log_scale;
}

// World covariance R diag(s^2) R^T; cov = (xx, xy, xz, yy, yz, zz).
template <typename T>
void Covariance3d(const T* log_scale, const T* quat, T* cov) {
  using std::exp;
  T R[9];
  QuatToRotation(quat, R);
  T s2[3];
  for (int i = 0; i < 3; ++i) s2[i] = exp(T(2) * ClampLogScale(log_scale[i]));
  auto entry = [&](int r, int c) {
    return R[r * 3 + 0] * R[c * 3 + 0] * s2[0] +
           R[r * 3 + 1] * R[c * 3 + 1] * s2[1] +
           R[r * 3 + 2] * R[c * 3 + 2] * s2[2];
  };
  cov[0] = entry(0, 0), cov[1] = entry(0, 1), cov[2] = entry(0, 2);
  cov[3] = entry(1, 1), cov[4] = entry(1, 2), cov[5] = entry(2, 2);
}

// Camera-frame point R * mean + t.
template <typename T>
void WorldToCamera(const ProjectionCamera& cam, const T* mean, T* tcam) {
  for (int r = 0; r < 3; ++r) {
    tcam[r] = T(cam.R[r * 3]) * mean[0] + T(cam.R[r * 3 + 1]) * mean[1] +
              T(cam.R[r * 3 + 2]) * mean[2] + T(cam.t[r]);
  }
}

// Pixel position (COLMAP convention) of camera-frame point tcam.
template <typename T>
void ProjectMean(const ProjectionCamera& cam, const T* tcam, T* mean2d) {
  mean2d[0] = T(cam.fx) * tcam[0] / tcam[2] + T(cam.cx);
  mean2d[1] = T(cam.fy) * tcam[1] / tcam[2] + T(cam.cy);
}

// The 2 x 3 EWA matrix J W (row-major) at camera point tcam, with Inria's
// clamp of x/z and y/z to 1.3 tan(half-FOV) inside the Jacobian.
template <typename T>
void ProjectionJacobian(const ProjectionCamera& cam, const T* tcam, T* JW) {
  const T limx = T(kFrustumClampFactor * cam.tan_fovx);
  const T limy = T(kFrustumClampFactor * cam.tan_fovy);
  T u = tcam[0] / tcam[2], v = tcam[1] / tcam[2];
  if (u < -limx) u = -limx;
  if (u > limx) u = limx;
  if (v < -limy) v = -limy;
  if (v > limy) v = limy;
  const T inv_z = T(1) / tcam[2];
  const T J[6] = {T(cam.fx) * inv_z,      T(0),
                  -T(cam.fx) * u * inv_z, T(0),
                  T(cam.fy) * inv_z,      -T(cam.fy) * v * inv_z};
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) {
      JW[r * 3 + c] = J[r * 3] * T(cam.R[c]) + J[r * 3 + 1] * T(cam.R[3 + c]) +
                      J[r * 3 + 2] * T(cam.R[6 + c]);
    }
  }
}

// Screen covariance (JW) cov3d (JW)^T + 0.3 I; cov2d = (xx, xy, yy).
template <typename T>
void Covariance2d(const ProjectionCamera& cam, const T* tcam, const T* cov3d,
                  T* cov2d) {
  T M[6];
  ProjectionJacobian(cam, tcam, M);
  const T S[9] = {cov3d[0], cov3d[1], cov3d[2], cov3d[1], cov3d[3],
                  cov3d[4], cov3d[2], cov3d[4], cov3d[5]};
  T MS[6];
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
  cov2d[0] = entry(0, 0) + T(kCovDilation);
  cov2d[1] = entry(0, 1);
  cov2d[2] = entry(1, 1) + T(kCovDilation);
}

// Conic (inverse covariance) (a, b, c): power = -0.5 (a dx^2 + c dy^2) -
// b dx dy. Returns false for a non-positive determinant.
template <typename T>
bool InvertCovariance2d(const T* cov2d, T* conic) {
  const T det = cov2d[0] * cov2d[2] - cov2d[1] * cov2d[1];
  if (!(det > T(0))) return false;
  const T inv = T(1) / det;
  conic[0] = cov2d[2] * inv;
  conic[1] = -cov2d[1] * inv;
  conic[2] = cov2d[0] * inv;
  return true;
}

// The whole differentiable chain: mean, log_scale, quat -> pixel mean and
// conic. Returns false where the conic is undefined. (Culling is separate.)
template <typename T>
bool ProjectGaussian(const ProjectionCamera& cam, const T* mean,
                     const T* log_scale, const T* quat, T* mean2d, T* conic) {
  T tcam[3], cov3d[6], cov2d[3];
  WorldToCamera(cam, mean, tcam);
  Covariance3d(log_scale, quat, cov3d);
  Covariance2d(cam, tcam, cov3d, cov2d);
  ProjectMean(cam, tcam, mean2d);
  return InvertCovariance2d(cov2d, conic);
}

// A range of tiles [x0, x1) x [y0, y1) in the full frame's tile grid.
struct TileRange {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// What the forward projection gives per visible Gaussian (double).
struct ProjectedGaussian {
  // Pixel-space mean (COLMAP convention) and conic (a, b, c).
  double mean2d[2], conic[3];
  // Screen covariance including dilation (xx, xy, yy).
  double cov2d[3];
  // Camera depth (sort key).
  double depth;
  // Inria's 3-sigma radius in pixels (> 0).
  double radius;
  // Tiles the Gaussian is binned into (Inria's getRect, full-frame grid).
  TileRange tiles;
};

// Projects one Gaussian; false if culled (non-finite input, outside the depth
// range, degenerate conic or no tile overlap). Inria semantics.
bool ProjectForward(const ProjectionCamera& cam, const float* mean,
                    const float* log_scale, const float* quat,
                    ProjectedGaussian* out);

// Cheap conservative test: false only if ProjectForward would cull the
// Gaussian or give it tiles outside `range` (bounds the 3-sigma radius by
// the Frobenius norm of the Jacobian and the largest scale). Lets crop
// renders skip most of the projection work for Gaussians outside the crop.
bool MayTouchTiles(const ProjectionCamera& cam, const float* mean,
                   const float* log_scale, const TileRange& range);

// Inria's 3-sigma screen radius in pixels of every Gaussian with visible[i]
// set (0 for the others and for culled ones): radii is resized to
// model.size(). Density control prunes on it.
void ComputeScreenRadii(const GaussianModel& model, const RenderCamera& camera,
                        const std::vector<uint8_t>& visible,
                        std::vector<float>* radii);

// Backward of ProjectGaussian: given dL/dmean2d (2) and dL/dconic (3, for the
// scalars a, b, c) adds dL/dmean (3), dL/dlog_scale (3), dL/dquat (4).
void ProjectBackward(const ProjectionCamera& cam, const float* mean,
                     const float* log_scale, const float* quat,
                     const double* grad_mean2d, const double* grad_conic,
                     double* grad_mean, double* grad_log_scale,
                     double* grad_quat);

}  // namespace watergs
