// View-dependent colour from real spherical harmonics, degree 0-3, with the
// constants and sign conventions of the Inria 3DGS code. The colour is the SH
// sum + 0.5 clamped at 0; the clamp is applied by the caller (and zeroes the
// gradient of clamped channels, as Inria does).
#pragma once

#include <cmath>

namespace watergs {

// Inria's real SH constants for bands 0-3.
inline constexpr double kShC0 = 0.28209479177387814;
inline constexpr double kShC1 = 0.4886025119029199;
inline constexpr double kShC2[5] = {1.0925484305920792, -1.0925484305920792,
                                    0.31539156525252005, -1.0925484305920792,
                                    0.5462742152960396};
inline constexpr double kShC3[7] = {-0.5900435899266435, 2.890611442640554,
                                    -0.4570457994644658, 0.3731763325901154,
                                    -0.4570457994644658, 1.445305721320277,
                                    -0.5900435899266435};

// The NumShCoeffs(degree) basis values at unit direction (x, y, z).
template <typename T>
void ShBasis(int degree, const T& x, const T& y, const T& z, T* basis) {
  basis[0] = T(kShC0);
  if (degree < 1) return;
  basis[1] = T(-kShC1) * y;
  basis[2] = T(kShC1) * z;
  basis[3] = T(-kShC1) * x;
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  basis[4] = T(kShC2[0]) * x * y;
  basis[5] = T(kShC2[1]) * y * z;
  basis[6] = T(kShC2[2]) * (T(2) * zz - xx - yy);
  basis[7] = T(kShC2[3]) * x * z;
  basis[8] = T(kShC2[4]) * (xx - yy);
  if (degree < 3) return;
  basis[9] = T(kShC3[0]) * y * (T(3) * xx - yy);
  basis[10] = T(kShC3[1]) * x * y * z;
  basis[11] = T(kShC3[2]) * y * (T(4) * zz - xx - yy);
  basis[12] = T(kShC3[3]) * z * (T(2) * zz - T(3) * xx - T(3) * yy);
  basis[13] = T(kShC3[4]) * x * (T(4) * zz - xx - yy);
  basis[14] = T(kShC3[5]) * z * (xx - yy);
  basis[15] = T(kShC3[6]) * x * (xx - T(3) * yy);
}

// Unclamped colour (SH sum + 0.5) for the view direction `dir` (any length,
// from the camera centre to the Gaussian). dc: 3 floats; rest: (K-1) x 3,
// coefficient major, rgb interleaved, K = NumShCoeffs(degree).
template <typename T, typename C>
void ShColorUnclamped(int degree, const C* dc, const C* rest, const T* dir,
                      T* rgb) {
  using std::sqrt;
  const T norm = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  // A Gaussian at the camera centre has no direction; any unit vector will do.
  const bool degenerate = !(norm > T(1e-30));
  const T x = degenerate ? T(0) : dir[0] / norm;
  const T y = degenerate ? T(0) : dir[1] / norm;
  const T z = degenerate ? T(1) : dir[2] / norm;
  T basis[16];
  ShBasis(degree, x, y, z, basis);
  for (int ch = 0; ch < 3; ++ch) {
    T sum = basis[0] * T(dc[ch]);
    for (int k = 1; k < (degree + 1) * (degree + 1); ++k) {
      sum += basis[k] * T(rest[(k - 1) * 3 + ch]);
    }
    rgb[ch] = sum + T(0.5);
  }
}

// Partial derivatives of the basis w.r.t. x, y, z (each NumShCoeffs values).
void ShBasisGradient(int degree, double x, double y, double z, double* d_dx,
                     double* d_dy, double* d_dz);

// Backward of ShColorUnclamped. grad_rgb: dL/d(unclamped colour), 3 values
// (the caller zeroes clamped channels). Adds into grad_dc (3),
// grad_rest ((K-1) x 3 of the model's stride, only the first K-1 written)
// and grad_dir (3, w.r.t. the unnormalised direction).
void ShColorBackward(int degree, const float* dc, const float* rest,
                     const double* dir, const double* grad_rgb, float* grad_dc,
                     float* grad_rest, double* grad_dir);

// Expands the factored SH gradient of one Gaussian (GaussianGradients with
// compact_sh): grad_rgb (3) and view direction dir (3, unnormalised) ->
// grad_dc (3) and grad_rest (rest_stride values, zero above `degree`),
// overwritten. The same products ShColorBackward accumulates.
void ShCoefficientGradients(int degree, const float* dir, const float* grad_rgb,
                            int rest_stride, float* grad_dc, float* grad_rest);

}  // namespace watergs
