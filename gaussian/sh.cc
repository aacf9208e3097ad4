// Hand-written backward of the SH colour; checked against ceres::Jet of the
// templates in sh.h by tests/gaussian/sh_test.cc.
#include "gaussian/sh.h"

#include <algorithm>
#include <cmath>

namespace watergs {

void ShBasisGradient(int degree, double x, double y, double z, double* d_dx,
                     double* d_dy, double* d_dz) {
  const int count = (degree + 1) * (degree + 1);
  for (int k = 0; k < count; ++k) d_dx[k] = d_dy[k] = d_dz[k] = 0;
  if (degree < 1) return;
  d_dy[1] = -kShC1;
  d_dz[2] = kShC1;
  d_dx[3] = -kShC1;
  if (degree < 2) return;
  const double xx = x * x, yy = y * y, zz = z * z;
  d_dx[4] = kShC2[0] * y, d_dy[4] = kShC2[0] * x;
  d_dy[5] = kShC2[1] * z, d_dz[5] = kShC2[1] * y;
  d_dx[6] = -2 * kShC2[2] * x, d_dy[6] = -2 * kShC2[2] * y;
  d_dz[6] = 4 * kShC2[2] * z;
  d_dx[7] = kShC2[3] * z, d_dz[7] = kShC2[3] * x;
  d_dx[8] = 2 * kShC2[4] * x, d_dy[8] = -2 * kShC2[4] * y;
  if (degree < 3) return;
  d_dx[9] = 6 * kShC3[0] * x * y, d_dy[9] = kShC3[0] * (3 * xx - 3 * yy);
  d_dx[10] = kShC3[1] * y * z, d_dy[10] = kShC3[1] * x * z;
  d_dz[10] = kShC3[1] * x * y;
  d_dx[11] = -2 * kShC3[2] * x * y;
  d_dy[11] = kShC3[2] * (4 * zz - xx - 3 * yy);
  d_dz[11] = 8 * kShC3[2] * y * z;
  d_dx[12] = -6 * kShC3[3] * x * z, d_dy[12] = -6 * kShC3[3] * y * z;
  d_dz[12] = kShC3[3] * (6 * zz - 3 * xx - 3 * yy);
  d_dx[13] = kShC3[4] * (4 * zz - 3 * xx - yy);
  d_dy[13] = -2 * kShC3[4] * x * y, d_dz[13] = 8 * kShC3[4] * x * z;
  d_dx[14] = 2 * kShC3[5] * x * z, d_dy[14] = -2 * kShC3[5] * y * z;
  d_dz[14] = kShC3[5] * (xx - yy);
  d_dx[15] = kShC3[6] * (3 * xx - 3 * yy), d_dy[15] = -6 * kShC3[6] * x * y;
}

namespace {

// dir / |dir| into x, y, z (and |dir|); false (and +z) for a zero direction.
bool UnitDirection(const double* dir, double* norm, double* x, double* y,
                   double* z) {
  *norm = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  const bool ok = *norm > 1e-30;
  *x = ok ? dir[0] / *norm : 0;
  *y = ok ? dir[1] / *norm : 0;
  *z = ok ? dir[2] / *norm : 1;
  return ok;
}

}  // namespace

void ShColorBackward(int degree, const float* dc, const float* rest,
                     const double* dir, const double* grad_rgb, float* grad_dc,
                     float* grad_rest, double* grad_dir) {
  (void)dc;
  double norm, x, y, z;
  const bool degenerate = !UnitDirection(dir, &norm, &x, &y, &z);
  double basis[16], d_dx[16], d_dy[16], d_dz[16];
  ShBasis(degree, x, y, z, basis);
  ShBasisGradient(degree, x, y, z, d_dx, d_dy, d_dz);
  const int count = (degree + 1) * (degree + 1);
  const double g0 = grad_rgb[0], g1 = grad_rgb[1], g2 = grad_rgb[2];
  grad_dc[0] += static_cast<float>(basis[0] * g0);
  grad_dc[1] += static_cast<float>(basis[0] * g1);
  grad_dc[2] += static_cast<float>(basis[0] * g2);
  // Coefficient-major: one pass over the (K-1) x 3 block.
  double grad_unit[3] = {0, 0, 0};
  for (int k = 1; k < count; ++k) {
    const float* c = rest + (k - 1) * 3;
    float* gc = grad_rest + (k - 1) * 3;
    gc[0] += static_cast<float>(basis[k] * g0);
    gc[1] += static_cast<float>(basis[k] * g1);
    gc[2] += static_cast<float>(basis[k] * g2);
    const double weight = c[0] * g0 + c[1] * g1 + c[2] * g2;
    grad_unit[0] += d_dx[k] * weight;
    grad_unit[1] += d_dy[k] * weight;
    grad_unit[2] += d_dz[k] * weight;
  }
  if (degenerate || degree == 0) return;
  // d(v/|v|)/dv = (I - u u^T) / |v|.
  const double dot = x * grad_unit[0] + y * grad_unit[1] + z * grad_unit[2];
  grad_dir[0] += (grad_unit[0] - x * dot) / norm;
  grad_dir[1] += (grad_unit[1] - y * dot) / norm;
  grad_dir[2] += (grad_unit[2] - z * dot) / norm;
}

void ShCoefficientGradients(int degree, const float* dir, const float* grad_rgb,
                            int rest_stride, float* grad_dc, float* grad_rest) {
  const double d[3] = {dir[0], dir[1], dir[2]};
  double norm, x, y, z, basis[16];
  UnitDirection(d, &norm, &x, &y, &z);
  ShBasis(degree, x, y, z, basis);
  std::fill_n(grad_rest, rest_stride, 0.f);
  for (int c = 0; c < 3; ++c) {
    grad_dc[c] = static_cast<float>(basis[0] * grad_rgb[c]);
  }
  for (int k = 1; k < (degree + 1) * (degree + 1); ++k) {
    for (int c = 0; c < 3; ++c) {
      grad_rest[(k - 1) * 3 + c] = static_cast<float>(basis[k] * grad_rgb[c]);
    }
  }
}

}  // namespace watergs
