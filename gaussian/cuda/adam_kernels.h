// Launch API of the CUDA Adam kernels (adam.cu): AdamUpdate of
// gaussian/adam.cc per value, the factored SH gradient expansion of
// ShCoefficientGradients, and the row gather that makes moments follow
// Gaussians under density control. Plain C++17 (shared by nvcc and the host
// compiler); the host-facing class is in cuda_adam.h.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace watergs {
namespace cuda_adam {

// Per-step scalars of one group's update, in float as torch computes them
// (Adam::StepConstants).
struct AdamConstants {
  float step_size, bias2_sqrt, w1, beta2, w2, eps;
};

// sh.h's basis constants (kShC0, kShC1, kShC2, kShC3), passed from the host
// so that one definition serves both.
struct ShConstants {
  double c0, c1, c2[5], c3[7];
};

// One Adam update of a group of n Gaussians x stride values from dense
// gradients. mask (nullable, n bytes): only Gaussians with mask[i] != 0
// are updated. *rejected (device) is increased by the number of rejected
// values (non-finite gradient, or an update that would be non-finite).
cudaError_t LaunchAdamDense(const AdamConstants& k, const float* grad, float* m,
                            float* v, float* p, size_t n, int stride,
                            const uint8_t* mask, unsigned long long* rejected,
                            cudaStream_t stream);

// The same update of f_dc (dc == true, stride 3) or f_rest (stride =
// 3 * (K - 1)) from factored SH gradients: color_grad and view_dir are N x 3
// (GaussianGradients::sh_color_grad, sh_view_dir), expanded per Gaussian as
// ShCoefficientGradients does at SH degree `degree`.
cudaError_t LaunchAdamFactoredSh(const AdamConstants& k, const ShConstants& sh,
                                 const float* color_grad, const float* view_dir,
                                 int degree, bool dc, float* m, float* v,
                                 float* p, size_t n, int stride,
                                 const uint8_t* mask,
                                 unsigned long long* rejected,
                                 cudaStream_t stream);

// out row i = in row index[i] (stride floats), or zeros where index[i] < 0;
// i < n_out. `out` must not alias `in`.
cudaError_t LaunchGatherRows(const float* in, const int64_t* index,
                             size_t n_out, int stride, float* out,
                             cudaStream_t stream);

}  // namespace cuda_adam
}  // namespace watergs
