// CUDA kernels of the neural-network module (see nn_kernels.h). Each
// mirrors one loop of nn_layers.cc: same formulas, same precision (double
// where the CPU accumulates in double), so outputs agree to float rounding.
#include <cmath>

#include "watermark/cuda/nn_kernels.h"

namespace watergs {
namespace nn_kernels {
namespace {

constexpr int kThreads = 256;

// Blocks for a grid-stride loop over n values.
int GridFor(size_t n) {
  const size_t blocks = (n + kThreads - 1) / kThreads;
  return int(blocks < 65536 ? (blocks > 0 ? blocks : 1) : 65536);
}

// Sum of v over the block (blockDim.x == kThreads); every thread gets it.
__device__ double BlockSum(double v) {
  __shared__ double shared[kThreads];
  shared[threadIdx.x] = v;
  __syncthreads();
  for (int stride = kThreads / 2; stride > 0; stride >>= 1) {
    if (threadIdx.x < stride)
      shared[threadIdx.x] += shared[threadIdx.x + stride];
    __syncthreads();
  }
  const double total = shared[0];
  __syncthreads();  // shared may be reused by the next call
  return total;
}

__global__ void ReluForwardKernel(float* x, size_t n) {
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x)
    x[i] = x[i] > 0.f ? x[i] : 0.f;
}

__global__ void ReluBackwardKernel(const float* y, float* dy, size_t n) {
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x)
    dy[i] = y[i] > 0.f ? dy[i] : 0.f;
}

// One block per plane.
__global__ void GlobalAvgPoolForwardKernel(const float* x, size_t hw,
                                           float* y) {
  const float* plane = x + size_t(blockIdx.x) * hw;
  double sum = 0.0;
  for (size_t i = threadIdx.x; i < hw; i += kThreads) sum += plane[i];
  sum = BlockSum(sum);
  if (threadIdx.x == 0) y[blockIdx.x] = float(sum / double(hw));
}

__global__ void GlobalAvgPoolBackwardKernel(const float* dy, int planes,
                                            size_t hw, float* dx) {
  const size_t n = size_t(planes) * hw;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x)
    dx[i] = dy[i / hw] / float(hw);
}

__global__ void BroadcastRowsKernel(const float* bias, int rows, int cols,
                                    float* y) {
  const size_t n = size_t(rows) * cols;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x)
    y[i] = bias[i % cols];
}

// One thread per column, rows in order (float, as the CPU's bias gradient).
__global__ void AddColumnSumsKernel(const float* x, int rows, int cols,
                                    float* sums) {
  const int col = blockIdx.x * blockDim.x + threadIdx.x;
  if (col >= cols) return;
  float total = sums[col];
  for (int r = 0; r < rows; ++r) total += x[size_t(r) * cols + col];
  sums[col] = total;
}

// One block per channel.
__global__ void BatchNormRunningUpdateKernel(const float* x, int n,
                                             int channels, size_t hw,
                                             float momentum,
                                             float* running_mean,
                                             float* running_var) {
  const int c = blockIdx.x;
  const double count = double(n) * hw;
  double sum = 0.0;
  for (int b = 0; b < n; ++b) {
    const float* p = x + (size_t(b) * channels + c) * hw;
    for (size_t i = threadIdx.x; i < hw; i += kThreads) sum += p[i];
  }
  const double mean = BlockSum(sum) / count;
  double sq = 0.0;
  for (int b = 0; b < n; ++b) {
    const float* p = x + (size_t(b) * channels + c) * hw;
    for (size_t i = threadIdx.x; i < hw; i += kThreads)
      sq += (p[i] - mean) * (p[i] - mean);
  }
  sq = BlockSum(sq);
  if (threadIdx.x != 0) return;
  const double var = sq / count;
  const double unbiased = count > 1 ? sq / (count - 1) : var;
  running_mean[c] = float((1 - momentum) * running_mean[c] + momentum * mean);
  running_var[c] = float((1 - momentum) * running_var[c] + momentum * unbiased);
}

__global__ void BatchNormInferenceBackwardDataKernel(
    const float* dy, const float* gamma, const float* running_var, float eps,
    int channels, size_t hw, size_t total, float* dx) {
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < total;
       i += size_t(gridDim.x) * blockDim.x) {
    const int c = int((i / hw) % channels);
    const double invstd = 1.0 / sqrt(double(running_var[c]) + eps);
    const double scale = gamma[c] * invstd;
    dx[i] = float(scale * dy[i]);
  }
}

// One block per channel.
__global__ void BatchNormInferenceParamGradsKernel(
    const float* x, const float* dy, const float* running_mean,
    const float* running_var, float eps, int n, int channels, size_t hw,
    float* dgamma, float* dbeta) {
  const int c = blockIdx.x;
  const double mean = running_mean[c];
  const double invstd = 1.0 / sqrt(double(running_var[c]) + eps);
  double sum_dy = 0.0, sum_dy_xhat = 0.0;
  for (int b = 0; b < n; ++b) {
    const size_t offset = (size_t(b) * channels + c) * hw;
    for (size_t i = threadIdx.x; i < hw; i += kThreads) {
      const float g = dy[offset + i];
      sum_dy += g;
      sum_dy_xhat += g * (x[offset + i] - mean) * invstd;
    }
  }
  sum_dy = BlockSum(sum_dy);
  sum_dy_xhat = BlockSum(sum_dy_xhat);
  if (threadIdx.x != 0) return;
  dgamma[c] += float(sum_dy_xhat);
  dbeta[c] += float(sum_dy);
}

__device__ double Softplus(double x) {
  return fmax(x, 0.0) + log1p(exp(-fabs(x)));
}

// One block.
__global__ void BceWithLogitsKernel(const float* logits, const float* targets,
                                    size_t n, double* loss, float* dlogits) {
  double total = 0.0;
  for (size_t i = threadIdx.x; i < n; i += kThreads) {
    const double z = logits[i], t = targets[i];
    // Each term skipped at weight 0: an infinite logit costs 0 for the bit
    // it predicts and +inf for the other, never inf - inf.
    if (t != 1) total += (1 - t) * Softplus(z);
    if (t != 0) total += t * Softplus(-z);
    if (dlogits) {
      const double e = exp(-fabs(z));
      const double sigmoid = z >= 0 ? 1.0 / (1.0 + e) : e / (1.0 + e);
      dlogits[i] = float((sigmoid - t) / double(n));
    }
  }
  total = BlockSum(total);
  if (threadIdx.x == 0) *loss = total / double(n);
}

// One block.
__global__ void MseLossKernel(const float* a, const float* b, size_t n,
                              float weight, double* loss, float* grad) {
  double total = 0.0;
  for (size_t i = threadIdx.x; i < n; i += kThreads) {
    const double d = double(a[i]) - b[i];
    total += d * d;
    if (grad) grad[i] += weight * float(2.0 * d / double(n));
  }
  total = BlockSum(total);
  if (threadIdx.x == 0) *loss = total / double(n);
}

__global__ void AdamKernel(float* value, const float* grad, float* m, float* v,
                           size_t n, AdamConstants k) {
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x) {
    const float g = isfinite(grad[i]) ? grad[i] : 0.f;
    m[i] = k.beta1 * m[i] + k.one_minus_beta1 * g;
    v[i] = k.beta2 * v[i] + k.one_minus_beta2 * g * g;
    value[i] -= k.step_size * m[i] / (sqrtf(v[i]) / k.root2 + k.eps);
  }
}

__global__ void AddKernel(const float* a, const float* b, size_t n,
                          float* out) {
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x)
    out[i] = a[i] + b[i];
}

// Over n * count * hw destination values.
__global__ void CopyChannelsKernel(const float* src, int n, int src_channels,
                                   int src_begin, int count, size_t hw,
                                   float* dst, int dst_channels,
                                   int dst_begin) {
  const size_t total = size_t(n) * count * hw;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < total;
       i += size_t(gridDim.x) * blockDim.x) {
    const size_t p = i % hw;
    const int c = int((i / hw) % count);
    const int b = int(i / (hw * count));
    dst[(size_t(b) * dst_channels + dst_begin + c) * hw + p] =
        src[(size_t(b) * src_channels + src_begin + c) * hw + p];
  }
}

__global__ void FillMessagePlanesKernel(const float* message, int n, int bits,
                                        size_t hw, float* dst,
                                        int dst_channels) {
  const size_t total = size_t(n) * bits * hw;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < total;
       i += size_t(gridDim.x) * blockDim.x) {
    const size_t p = i % hw;
    const int bit = int((i / hw) % bits);
    const int b = int(i / (hw * bits));
    dst[(size_t(b) * dst_channels + bit) * hw + p] =
        message[size_t(b) * bits + bit];
  }
}

// Offset in a pitched HWC patch of NCHW plane position p (of width w).
__device__ size_t PatchOffset(size_t p, int w, int pitch, size_t c) {
  return ((p / w) * size_t(pitch) + p % w) * 3 + c;
}

// Over 3 * w * h values, in NCHW order.
__global__ void ImageToInputKernel(const float* hwc, int w, int h, int pitch,
                                   float* nchw) {
  const size_t hw = size_t(w) * h;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < 3 * hw;
       i += size_t(gridDim.x) * blockDim.x) {
    nchw[i] = 2.f * hwc[PatchOffset(i % hw, w, pitch, i / hw)] - 1.f;
  }
}

__global__ void InputGradientToImageKernel(const float* dnchw, int w, int h,
                                           int pitch, bool accumulate,
                                           float* dhwc) {
  const size_t hw = size_t(w) * h;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < 3 * hw;
       i += size_t(gridDim.x) * blockDim.x) {
    float* dst = dhwc + PatchOffset(i % hw, w, pitch, i / hw);
    // The CPU forms the gradient image first, then adds it (embedder.cc).
    const float g = 2.f * dnchw[i];
    *dst = accumulate ? __fadd_rn(*dst, g) : g;
  }
}

}  // namespace

cudaError_t ReluForward(float* x, size_t n) {
  if (n > 0) ReluForwardKernel<<<GridFor(n), kThreads>>>(x, n);
  return cudaGetLastError();
}

cudaError_t ReluBackward(const float* y, float* dy, size_t n) {
  if (n > 0) ReluBackwardKernel<<<GridFor(n), kThreads>>>(y, dy, n);
  return cudaGetLastError();
}

cudaError_t GlobalAvgPoolForward(const float* x, int planes, size_t hw,
                                 float* y) {
  if (planes > 0) GlobalAvgPoolForwardKernel<<<planes, kThreads>>>(x, hw, y);
  return cudaGetLastError();
}

cudaError_t GlobalAvgPoolBackward(const float* dy, int planes, size_t hw,
                                  float* dx) {
  const size_t n = size_t(planes) * hw;
  if (n > 0)
    GlobalAvgPoolBackwardKernel<<<GridFor(n), kThreads>>>(dy, planes, hw, dx);
  return cudaGetLastError();
}

cudaError_t BroadcastRows(const float* bias, int rows, int cols, float* y) {
  const size_t n = size_t(rows) * cols;
  if (n > 0) BroadcastRowsKernel<<<GridFor(n), kThreads>>>(bias, rows, cols, y);
  return cudaGetLastError();
}

cudaError_t AddColumnSums(const float* x, int rows, int cols, float* sums) {
  if (cols > 0)
    AddColumnSumsKernel<<<GridFor(size_t(cols)), kThreads>>>(x, rows, cols,
                                                             sums);
  return cudaGetLastError();
}

cudaError_t BatchNormRunningUpdate(const float* x, int n, int channels,
                                   size_t hw, float momentum,
                                   float* running_mean, float* running_var) {
  if (channels > 0)
    BatchNormRunningUpdateKernel<<<channels, kThreads>>>(
        x, n, channels, hw, momentum, running_mean, running_var);
  return cudaGetLastError();
}

cudaError_t BatchNormInferenceBackwardData(const float* dy, const float* gamma,
                                           const float* running_var, float eps,
                                           int n, int channels, size_t hw,
                                           float* dx) {
  const size_t total = size_t(n) * channels * hw;
  if (total > 0)
    BatchNormInferenceBackwardDataKernel<<<GridFor(total), kThreads>>>(
        dy, gamma, running_var, eps, channels, hw, total, dx);
  return cudaGetLastError();
}

cudaError_t BatchNormInferenceParamGrads(const float* x, const float* dy,
                                         const float* running_mean,
                                         const float* running_var, float eps,
                                         int n, int channels, size_t hw,
                                         float* dgamma, float* dbeta) {
  if (channels > 0)
    BatchNormInferenceParamGradsKernel<<<channels, kThreads>>>(
        x, dy, running_mean, running_var, eps, n, channels, hw, dgamma, dbeta);
  return cudaGetLastError();
}

cudaError_t BceWithLogits(const float* logits, const float* targets, size_t n,
                          double* loss, float* dlogits) {
  BceWithLogitsKernel<<<1, kThreads>>>(logits, targets, n, loss, dlogits);
  return cudaGetLastError();
}

cudaError_t MseLoss(const float* a, const float* b, size_t n, float weight,
                    double* loss, float* grad) {
  MseLossKernel<<<1, kThreads>>>(a, b, n, weight, loss, grad);
  return cudaGetLastError();
}

cudaError_t AdamStep(float* value, const float* grad, float* m, float* v,
                     size_t n, AdamConstants constants) {
  if (n > 0)
    AdamKernel<<<GridFor(n), kThreads>>>(value, grad, m, v, n, constants);
  return cudaGetLastError();
}

cudaError_t Add(const float* a, const float* b, size_t n, float* out) {
  if (n > 0) AddKernel<<<GridFor(n), kThreads>>>(a, b, n, out);
  return cudaGetLastError();
}

cudaError_t CopyChannels(const float* src, int n, int src_channels,
                         int src_begin, int count, size_t hw, float* dst,
                         int dst_channels, int dst_begin) {
  const size_t total = size_t(n) * count * hw;
  if (total > 0)
    CopyChannelsKernel<<<GridFor(total), kThreads>>>(src, n, src_channels,
                                                     src_begin, count, hw, dst,
                                                     dst_channels, dst_begin);
  return cudaGetLastError();
}

cudaError_t FillMessagePlanes(const float* message, int n, int bits, size_t hw,
                              float* dst, int dst_channels) {
  const size_t total = size_t(n) * bits * hw;
  if (total > 0)
    FillMessagePlanesKernel<<<GridFor(total), kThreads>>>(message, n, bits, hw,
                                                          dst, dst_channels);
  return cudaGetLastError();
}

cudaError_t ImageToInput(const float* hwc, int width, int height, int pitch,
                         float* nchw) {
  const size_t hw = size_t(width) * size_t(height);
  if (hw > 0) {
    ImageToInputKernel<<<GridFor(3 * hw), kThreads>>>(hwc, width, height, pitch,
                                                      nchw);
  }
  return cudaGetLastError();
}

cudaError_t InputGradientToImage(const float* dnchw, int width, int height,
                                 int pitch, bool accumulate, float* dhwc) {
  const size_t hw = size_t(width) * size_t(height);
  if (hw > 0) {
    InputGradientToImageKernel<<<GridFor(3 * hw), kThreads>>>(
        dnchw, width, height, pitch, accumulate, dhwc);
  }
  return cudaGetLastError();
}

}  // namespace nn_kernels
}  // namespace watergs
