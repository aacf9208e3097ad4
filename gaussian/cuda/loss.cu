// CUDA kernels of the training loss (see loss_kernels.h). Each kernel is one
// step of gaussian/loss.cc's SsimInterleaved: horizontal blur of the five
// moment planes, vertical blur + SSIM map + adjoints, then the same two
// blurs over the adjoints and the gradient. Float arithmetic goes through
// the __f*_rn intrinsics in the CPU code's order: nvcc fuses no multiply-add,
// so the device result is fixed by the source alone. (GCC may fuse some on
// the CPU, -ffp-contract=fast being its C++ default, so the two agree to
// float rounding, not bit for bit.)
#include "gaussian/cuda/loss_kernels.h"

namespace watergs {
namespace cuda_loss {
namespace {

constexpr int kRadius = 5;
constexpr int kThreads = 256;

__device__ __forceinline__ float Mul(float a, float b) {
  return __fmul_rn(a, b);
}
__device__ __forceinline__ float Add(float a, float b) {
  return __fadd_rn(a, b);
}
__device__ __forceinline__ float Sub(float a, float b) {
  return __fsub_rn(a, b);
}
__device__ __forceinline__ float Div(float a, float b) {
  return __fdiv_rn(a, b);
}

unsigned Blocks(size_t count) {
  return static_cast<unsigned>((count + kThreads - 1) / kThreads);
}

__global__ void L1Kernel(const float* x, const float* y, size_t count,
                         float inv_count, float* abs_diff, float* grad) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= count) return;
  const float d = Sub(x[j], y[j]);
  abs_diff[j] = fabsf(d);
  if (grad) grad[j] = d > 0 ? inv_count : (d < 0 ? -inv_count : 0.f);
}

__global__ void SquaredErrorKernel(const float* x, const float* y, size_t count,
                                   float grad_scale, float* sq_diff,
                                   float* grad) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= count) return;
  const float d = Sub(x[j], y[j]);
  sq_diff[j] = Mul(d, d);
  if (grad) grad[j] = Mul(grad_scale, d);
}

// Horizontal blur of `planes` planes of height x len values, taps `stride`
// values apart, zero padded; plane p of the input is produced by load(p, j).
// CPU order: out = 0, then out += g[k] * in for k = 0..10 (padding adds +0).
template <int kPlanes, typename Load>
__device__ void HorizontalBlur(const SsimWindow& w, int len, int stride,
                               size_t row_start, int i, Load&& load,
                               float* out) {
  for (int p = 0; p < kPlanes; ++p) out[p] = 0.f;
  for (int k = 0; k < 11; ++k) {
    const int at = i + (k - kRadius) * stride;
    if (at < 0 || at >= len) continue;
    float v[kPlanes];
    load(row_start + at, v);
    for (int p = 0; p < kPlanes; ++p) out[p] = Add(out[p], Mul(w.g[k], v[p]));
  }
}

// Planes 0-4 of scratch: horizontal blurs of x, y, x^2, y^2, xy.
__global__ void BlurMomentsRowsKernel(const float* x, const float* y,
                                      int height, int len, int stride,
                                      SsimWindow w, float* scratch) {
  const size_t plane = size_t(height) * len;
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= plane) return;
  const int i = static_cast<int>(j % len);
  const size_t row_start = j - i;
  float out[5];
  HorizontalBlur<5>(
      w, len, stride, row_start, i,
      [&](size_t at, float* v) {
        const float a = x[at], b = y[at];
        v[0] = a;
        v[1] = b;
        v[2] = Mul(a, a);
        v[3] = Mul(b, b);
        v[4] = Mul(a, b);
      },
      out);
  for (int p = 0; p < 5; ++p) scratch[p * plane + j] = out[p];
}

// Vertical blur of `kPlanes` planes (plane p at in + p * plane), rows out of
// the image skipped as the CPU's ring does.
template <int kPlanes>
__device__ void VerticalBlur(const SsimWindow& w, const float* in, int height,
                             int len, size_t plane, size_t j, float* out) {
  const int row = static_cast<int>(j / len);
  for (int p = 0; p < kPlanes; ++p) out[p] = 0.f;
  for (int k = 0; k < 11; ++k) {
    const int r = row + k - kRadius;
    if (r < 0 || r >= height) continue;
    const size_t at = j + (ptrdiff_t(r) - row) * len;
    for (int p = 0; p < kPlanes; ++p) {
      out[p] = Add(out[p], Mul(w.g[k], in[p * plane + at]));
    }
  }
}

// The SSIM map (plane 8) and, if wanted, its adjoints (planes 5-7), from the
// local moments; loss.cc's ssim_row, S = A1 A2 / (B1 B2).
__global__ void SsimMapKernel(int height, int len, SsimWindow w, float c1,
                              float c2, float inv_count, bool want_adjoint,
                              float* scratch) {
  const size_t plane = size_t(height) * len;
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= plane) return;
  float mom[5];
  VerticalBlur<5>(w, scratch, height, len, plane, j, mom);
  const float mx = mom[0], my = mom[1], exx = mom[2], eyy = mom[3],
              exy = mom[4];
  const float a1 = Add(Mul(Mul(2.f, mx), my), c1);
  const float a2 = Add(Mul(2.f, Sub(exy, Mul(mx, my))), c2);
  const float b1 = Add(Add(Mul(mx, mx), Mul(my, my)), c1);
  const float b2 = Add(Add(Sub(exx, Mul(mx, mx)), Sub(eyy, Mul(my, my))), c2);
  const float ssim = Div(Mul(a1, a2), Mul(b1, b2));
  scratch[8 * plane + j] = ssim;
  if (!want_adjoint) return;
  const float two_my = Mul(2.f, my), two_mx = Mul(2.f, mx);
  const float bracket =
      Add(Sub(Sub(Div(two_my, a1), Div(two_my, a2)), Div(two_mx, b1)),
          Div(two_mx, b2));
  scratch[5 * plane + j] = Mul(Mul(inv_count, ssim), bracket);
  scratch[6 * plane + j] = Div(Mul(-inv_count, ssim), b2);
  scratch[7 * plane + j] = Div(Mul(Mul(inv_count, 2.f), a1), Mul(b1, b2));
}

// Planes 0-2: horizontal blurs of the adjoint planes 5-7 (the window is
// symmetric, so the adjoint of the correlation is the same correlation).
__global__ void BlurAdjointRowsKernel(int height, int len, int stride,
                                      SsimWindow w, float* scratch) {
  const size_t plane = size_t(height) * len;
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= plane) return;
  const int i = static_cast<int>(j % len);
  const size_t row_start = j - i;
  const float* adj = scratch + 5 * plane;
  float out[3];
  HorizontalBlur<3>(
      w, len, stride, row_start, i,
      [&](size_t at, float* v) {
        for (int p = 0; p < 3; ++p) v[p] = adj[p * plane + at];
      },
      out);
  for (int p = 0; p < 3; ++p) scratch[p * plane + j] = out[p];
}

// grad = b_mu + 2 x b_xx + y b_xy (loss.cc's gradient_row), optionally
// combined with the L1 gradient already in grad.
__global__ void SsimGradientKernel(const float* x, const float* y, int height,
                                   int len, SsimWindow w, const float* scratch,
                                   bool combine, float w_l1, float w_ssim,
                                   float* grad) {
  const size_t plane = size_t(height) * len;
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= plane) return;
  float b[3];
  VerticalBlur<3>(w, scratch, height, len, plane, j, b);
  const float gs = Add(Add(b[0], Mul(Mul(2.f, x[j]), b[1])), Mul(y[j], b[2]));
  grad[j] = combine ? Add(Mul(w_l1, grad[j]), Mul(w_ssim, gs)) : gs;
}

// Block b sums values b * kThreads + t + k * (blocks * kThreads) per thread
// t, then a fixed shared-memory tree: the order depends on count alone.
__global__ void PartialSumKernel(const float* values, size_t count,
                                 double* partials) {
  __shared__ double tree[kThreads];
  const size_t step = size_t(gridDim.x) * kThreads;
  double sum = 0;
  for (size_t j = blockIdx.x * size_t(kThreads) + threadIdx.x; j < count;
       j += step) {
    sum += values[j];
  }
  tree[threadIdx.x] = sum;
  __syncthreads();
  for (int half = kThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) tree[threadIdx.x] += tree[threadIdx.x + half];
    __syncthreads();
  }
  if (threadIdx.x == 0) partials[blockIdx.x] = tree[0];
}

__global__ void FinalSumKernel(const double* partials, int count, double* sum) {
  double total = 0;
  for (int b = 0; b < count; ++b) total += partials[b];
  *sum = total;
}

}  // namespace

cudaError_t LaunchL1(const float* x, const float* y, size_t count,
                     float inv_count, float* abs_diff, float* grad,
                     cudaStream_t stream) {
  if (count == 0) return cudaSuccess;
  L1Kernel<<<Blocks(count), kThreads, 0, stream>>>(x, y, count, inv_count,
                                                   abs_diff, grad);
  return cudaGetLastError();
}

cudaError_t LaunchSquaredError(const float* x, const float* y, size_t count,
                               float grad_scale, float* sq_diff, float* grad,
                               cudaStream_t stream) {
  if (count == 0) return cudaSuccess;
  SquaredErrorKernel<<<Blocks(count), kThreads, 0, stream>>>(
      x, y, count, grad_scale, sq_diff, grad);
  return cudaGetLastError();
}

cudaError_t LaunchSsimForward(const float* x, const float* y, int width,
                              int height, int channels,
                              const SsimWindow& window, float c1, float c2,
                              float inv_count, bool want_adjoint,
                              float* scratch, cudaStream_t stream) {
  const int len = width * channels;
  const size_t plane = size_t(height) * len;
  if (plane == 0) return cudaSuccess;
  BlurMomentsRowsKernel<<<Blocks(plane), kThreads, 0, stream>>>(
      x, y, height, len, channels, window, scratch);
  cudaError_t status = cudaGetLastError();
  if (status != cudaSuccess) return status;
  SsimMapKernel<<<Blocks(plane), kThreads, 0, stream>>>(
      height, len, window, c1, c2, inv_count, want_adjoint, scratch);
  return cudaGetLastError();
}

cudaError_t LaunchSsimBackward(const float* x, const float* y, int width,
                               int height, int channels,
                               const SsimWindow& window, float* scratch,
                               bool combine, float w_l1, float w_ssim,
                               float* grad, cudaStream_t stream) {
  const int len = width * channels;
  const size_t plane = size_t(height) * len;
  if (plane == 0) return cudaSuccess;
  BlurAdjointRowsKernel<<<Blocks(plane), kThreads, 0, stream>>>(
      height, len, channels, window, scratch);
  cudaError_t status = cudaGetLastError();
  if (status != cudaSuccess) return status;
  SsimGradientKernel<<<Blocks(plane), kThreads, 0, stream>>>(
      x, y, height, len, window, scratch, combine, w_l1, w_ssim, grad);
  return cudaGetLastError();
}

cudaError_t LaunchDeterministicSum(const float* values, size_t count,
                                   double* partials, double* sum,
                                   cudaStream_t stream) {
  size_t blocks = (count + kThreads - 1) / kThreads;
  if (blocks < 1) blocks = 1;
  if (blocks > size_t(kMaxPartials)) blocks = kMaxPartials;
  PartialSumKernel<<<static_cast<unsigned>(blocks), kThreads, 0, stream>>>(
      values, count, partials);
  cudaError_t status = cudaGetLastError();
  if (status != cudaSuccess) return status;
  FinalSumKernel<<<1, 1, 0, stream>>>(partials, static_cast<int>(blocks), sum);
  return cudaGetLastError();
}

}  // namespace cuda_loss
}  // namespace watergs
