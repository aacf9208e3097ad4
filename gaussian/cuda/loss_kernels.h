// Launch API of the CUDA loss kernels (loss.cu): L1 and SSIM with their
// analytic backward, the same formulas and the same order of float
// operations as gaussian/loss.cc. Plain C++17 so that nvcc and the host
// compiler share it; the host-facing class is in cuda_loss.h.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>

namespace watergs {
namespace cuda_loss {

// The 11 taps of the normalised 1-D Gaussian window (as loss.cc builds it).
struct SsimWindow {
  // Taps g[0..10], centre at 5.
  float g[11];
};

// Floats of scratch per image value (height * width * channels) that
// LaunchSsimForward and LaunchSsimBackward need: 5 horizontally blurred
// moment planes, 3 adjoint planes and the SSIM map.
constexpr int kSsimScratchPlanes = 9;

// Doubles of `partials` that LaunchDeterministicSum needs.
constexpr int kMaxPartials = 1024;

// |x - y| per value into abs_diff (count floats); grad (nullable) gets
// sign(x - y) * inv_count as L1Interleaved writes it.
cudaError_t LaunchL1(const float* x, const float* y, size_t count,
                     float inv_count, float* abs_diff, float* grad,
                     cudaStream_t stream);

// (x - y)^2 per value into sq_diff (count floats); grad (nullable) gets
// grad_scale * (x - y), as the embedder's host MSE term writes it.
cudaError_t LaunchSquaredError(const float* x, const float* y, size_t count,
                               float grad_scale, float* sq_diff, float* grad,
                               cudaStream_t stream);

// SSIM map of x against y (height rows of width * channels values) into
// scratch plane 8; with want_adjoint also the three adjoint planes (dS/dmu_x,
// dS/dE[x^2], dS/dE[xy], times inv_count) into planes 5-7. `scratch` holds
// kSsimScratchPlanes * height * width * channels floats.
cudaError_t LaunchSsimForward(const float* x, const float* y, int width,
                              int height, int channels,
                              const SsimWindow& window, float c1, float c2,
                              float inv_count, bool want_adjoint,
                              float* scratch, cudaStream_t stream);

// d(mean SSIM)/dx from the adjoint planes of LaunchSsimForward (planes 0-2
// are reused as scratch). combine == false: grad = dSSIM/dx. combine ==
// true: grad = w_l1 * grad + w_ssim * dSSIM/dx (grad holds the L1 gradient),
// the training loss's combination in TrainingLoss::Evaluate's float order.
cudaError_t LaunchSsimBackward(const float* x, const float* y, int width,
                               int height, int channels,
                               const SsimWindow& window, float* scratch,
                               bool combine, float w_l1, float w_ssim,
                               float* grad, cudaStream_t stream);

// *sum = sum of values[0..count) in double, in an order fixed by `count`
// alone (per-block partial sums, then one thread adds the partials in
// order), so the result never depends on scheduling. partials holds
// kMaxPartials doubles; sum is one device double.
cudaError_t LaunchDeterministicSum(const float* values, size_t count,
                                   double* partials, double* sum,
                                   cudaStream_t stream);

}  // namespace cuda_loss
}  // namespace watergs
