// Plain C++17 launch API of the neural-network module's own CUDA kernels
// (nn_kernels.cu): the element-wise and per-channel pieces cuDNN/cuBLAS do
// not cover, written with the CPU layers' formulas (nn_layers.cc) so that a
// parity mismatch is easy to trace. Every pointer is device memory, tensors
// are NCHW float, everything runs on the default stream, and every launcher
// returns cudaGetLastError() for the caller's WATERGS_CUDA_CHECK.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>

namespace watergs {
namespace nn_kernels {

// x = max(x, 0) in place, n values.
cudaError_t ReluForward(float* x, size_t n);
// dy *= (y > 0) in place, y the ReLU output.
cudaError_t ReluBackward(const float* y, float* dy, size_t n);

// x [planes, hw] -> y [planes]: the mean of each plane (double sums).
cudaError_t GlobalAvgPoolForward(const float* x, int planes, size_t hw,
                                 float* y);
// dy [planes] -> dx [planes, hw] = dy / hw.
cudaError_t GlobalAvgPoolBackward(const float* dy, int planes, size_t hw,
                                  float* dx);

// y [rows, cols] = bias [cols] on every row.
cudaError_t BroadcastRows(const float* bias, int rows, int cols, float* y);
// sums [cols] += column sums of x [rows, cols].
cudaError_t AddColumnSums(const float* x, int rows, int cols, float* sums);

// BatchNorm training statistics as the CPU computes them: per channel of
// x [n, channels, hw], two-pass mean and biased variance in double, then
// running_mean/var = (1 - momentum) running + momentum (mean, unbiased var),
// unbiased = var * count / (count - 1) when count = n * hw > 1.
cudaError_t BatchNormRunningUpdate(const float* x, int n, int channels,
                                   size_t hw, float momentum,
                                   float* running_mean, float* running_var);
// Inference-mode BatchNorm backward to the input: dx = dy * gamma /
// sqrt(running_var + eps) per channel (double scale, as the CPU).
cudaError_t BatchNormInferenceBackwardData(const float* dy, const float* gamma,
                                           const float* running_var, float eps,
                                           int n, int channels, size_t hw,
                                           float* dx);
// Inference-mode BatchNorm parameter gradients: dgamma += sum dy * xhat,
// dbeta += sum dy per channel, xhat from the running statistics.
cudaError_t BatchNormInferenceParamGrads(const float* x, const float* dy,
                                         const float* running_mean,
                                         const float* running_var, float eps,
                                         int n, int channels, size_t hw,
                                         float* dgamma, float* dbeta);

// Mean BCE with logits over n values (targets 0/1 or in [0,1]) into *loss
// (one double on the device); dlogits (if not null) = (sigmoid - t) / n.
// Same stable form as the CPU: (1 - t) softplus(z) + t softplus(-z).
cudaError_t BceWithLogits(const float* logits, const float* targets, size_t n,
                          double* loss, float* dlogits);
// Mean squared difference of a and b into *loss (device double); when
// grad is not null, grad += weight * float(2 (a - b) / n) (the CPU's MSE
// gradient, scaled and accumulated as the training step does).
cudaError_t MseLoss(const float* a, const float* b, size_t n, float weight,
                    double* loss, float* grad);

// One Adam update of n values; the bias-corrected step size and
// sqrt(1 - beta2^t) come from the host (double, then float, as the CPU).
// Non-finite gradients count as 0.
struct AdamConstants {
  // beta1, 1 - beta1, beta2, 1 - beta2, eps (all float as on the CPU).
  float beta1, one_minus_beta1, beta2, one_minus_beta2, eps;
  // learning_rate / (1 - beta1^t) and sqrt(1 - beta2^t).
  float step_size, root2;
};
cudaError_t AdamStep(float* value, const float* grad, float* m, float* v,
                     size_t n, AdamConstants constants);

// out = a + b, n values.
cudaError_t Add(const float* a, const float* b, size_t n, float* out);
// Copies channels [src_begin, src_begin + count) of src [n, src_channels,
// hw] into channels [dst_begin, ...) of dst [n, dst_channels, hw].
cudaError_t CopyChannels(const float* src, int n, int src_channels,
                         int src_begin, int count, size_t hw, float* dst,
                         int dst_channels, int dst_begin);
// Fills planes [0, bits) of dst [n, dst_channels, hw] with message[b * bits
// + i] (the encoder's replicated message).
cudaError_t FillMessagePlanes(const float* message, int n, int bits, size_t hw,
                              float* dst, int dst_channels);

// A width x height patch of an ImageRGB-layout image (HWC in [0,1], rows
// `pitch` pixels apart; hwc points at the patch's first pixel) -> network
// input [1,3,H,W] = 2 v - 1.
cudaError_t ImageToInput(const float* hwc, int width, int height, int pitch,
                         float* nchw);
// Gradient back into the same patch layout: dhwc[y pitch + x][c] =
// 2 dnchw[c][y][x], or += it when accumulate.
cudaError_t InputGradientToImage(const float* dnchw, int width, int height,
                                 int pitch, bool accumulate, float* dhwc);

}  // namespace nn_kernels
}  // namespace watergs
