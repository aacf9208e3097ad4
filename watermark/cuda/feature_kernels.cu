// The random-feature decoder's kernels (see feature_kernels.h). Float
// arithmetic goes through __f*_rn intrinsics in the CPU code's order, so
// nvcc contracts nothing into a fused multiply-add.
#include "watermark/cuda/feature_kernels.h"

namespace watergs {
namespace feature_kernels {
namespace {

constexpr int kThreads = 256;

unsigned GridFor(size_t n) {
  const size_t blocks = (n + kThreads - 1) / kThreads;
  return static_cast<unsigned>(blocks < 65535 ? (blocks > 0 ? blocks : 1)
                                              : 65535);
}

// One thread per pooled value: the CPU adds each block's input values into
// a zeroed output row by row, left to right, then scales by 1 / p^2.
__global__ void ImageToPooledKernel(const float* hwc, int pw, int ph, int pitch,
                                    int p, float scale, float* pooled) {
  const size_t plane = size_t(pw) * ph;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < 3 * plane;
       i += size_t(gridDim.x) * blockDim.x) {
    const int c = int(i / plane);
    const int y = int(i % plane / pw), x = int(i % pw);
    float sum = 0.f;
    for (int r = 0; r < p; ++r) {
      const float* row = hwc + (size_t(y * p + r) * pitch + size_t(x) * p) * 3;
      for (int col = 0; col < p; ++col) {
        const float v = __fsub_rn(__fmul_rn(2.f, row[col * 3 + c]), 1.f);
        sum = __fadd_rn(sum, v);
      }
    }
    pooled[i] = __fmul_rn(sum, scale);
  }
}

// One thread per column entry.
__global__ void Im2ColKernel(const float* pooled, int in, int ph, int pw, int k,
                             float* cols) {
  const size_t plane = size_t(ph) * pw;
  const int rows = in * k * k;
  const size_t n = (rows + 1) * plane;
  const int pad = k / 2;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x) {
    const int row = int(i / plane);
    const int y = int(i % plane / pw), x = int(i % pw);
    float v = 1.f;
    if (row < rows) {
      const int c = row / (k * k), dy = row / k % k, dx = row % k;
      const int sy = y + dy - pad, sx = x + dx - pad;
      v = sy >= 0 && sy < ph && sx >= 0 && sx < pw
              ? pooled[(size_t(c) * ph + sy) * pw + sx]
              : 0.f;
    }
    cols[i] = v;
  }
}

// One thread per input value: the output pixels whose window holds it.
__global__ void Col2ImKernel(const float* dcols, int in, int ph, int pw, int k,
                             float* dpooled) {
  const size_t plane = size_t(ph) * pw;
  const size_t n = size_t(in) * plane;
  const int pad = k / 2;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x) {
    const int c = int(i / plane);
    const int y = int(i % plane / pw), x = int(i % pw);
    float sum = 0.f;
    for (int dy = 0; dy < k; ++dy) {
      const int oy = y - dy + pad;
      if (oy < 0 || oy >= ph) continue;
      for (int dx = 0; dx < k; ++dx) {
        const int ox = x - dx + pad;
        if (ox < 0 || ox >= pw) continue;
        const int row = (c * k + dy) * k + dx;
        sum = __fadd_rn(sum, dcols[row * plane + size_t(oy) * pw + ox]);
      }
    }
    dpooled[i] = sum;
  }
}

// One block per channel: per-thread double sums of max(y, 0), then a fixed
// shared-memory tree (the order depends on hw alone).
__global__ void ReluGlobalAvgPoolKernel(const float* conv, size_t hw,
                                        float* features) {
  __shared__ double tree[kThreads];
  const float* plane = conv + size_t(blockIdx.x) * hw;
  double sum = 0;
  for (size_t i = threadIdx.x; i < hw; i += kThreads) {
    const float v = plane[i];
    sum += v > 0.f ? v : 0.f;
  }
  tree[threadIdx.x] = sum;
  __syncthreads();
  for (int half = kThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) tree[threadIdx.x] += tree[threadIdx.x + half];
    __syncthreads();
  }
  if (threadIdx.x == 0) features[blockIdx.x] = float(tree[0] / double(hw));
}

__global__ void ReluGlobalAvgPoolBackwardKernel(const float* dfeatures,
                                                const float* conv, int channels,
                                                size_t hw, float* dconv) {
  const size_t n = size_t(channels) * hw;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x) {
    const float g = __fdiv_rn(dfeatures[i / hw], float(hw));
    dconv[i] = conv[i] > 0.f ? g : 0.f;
  }
}

// One thread per patch value (HWC order).
__global__ void PooledGradientKernel(const float* dpooled, int width,
                                     int height, int pitch, int p, float scale,
                                     bool accumulate, float* dhwc) {
  const int pw = width / p, ph = height / p;
  const size_t n = size_t(width) * height * 3;
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n;
       i += size_t(gridDim.x) * blockDim.x) {
    const int c = int(i % 3);
    const int x = int(i / 3 % width), y = int(i / 3 / width);
    float g = 0.f;
    if (x < pw * p && y < ph * p) {
      const float d = dpooled[(size_t(c) * ph + y / p) * pw + x / p];
      // AvgPoolBackward's d / p^2, then the image's 2 x (input = 2 v - 1).
      g = __fmul_rn(2.f, __fmul_rn(d, scale));
    }
    float* dst = dhwc + (size_t(y) * pitch + x) * 3 + c;
    *dst = accumulate ? __fadd_rn(*dst, g) : g;
  }
}

}  // namespace

cudaError_t ImageToPooledInput(const float* hwc, int width, int height,
                               int pitch, int p, float* pooled) {
  const int pw = width / p, ph = height / p;
  const size_t n = 3 * size_t(pw) * ph;
  if (n == 0) return cudaSuccess;
  ImageToPooledKernel<<<GridFor(n), kThreads>>>(hwc, pw, ph, pitch, p,
                                                1.f / float(p * p), pooled);
  return cudaGetLastError();
}

cudaError_t Im2Col(const float* pooled, int in, int ph, int pw, int k,
                   float* cols) {
  const size_t n = (size_t(in) * k * k + 1) * ph * pw;
  if (n == 0) return cudaSuccess;
  Im2ColKernel<<<GridFor(n), kThreads>>>(pooled, in, ph, pw, k, cols);
  return cudaGetLastError();
}

cudaError_t Col2Im(const float* dcols, int in, int ph, int pw, int k,
                   float* dpooled) {
  const size_t n = size_t(in) * ph * pw;
  if (n == 0) return cudaSuccess;
  Col2ImKernel<<<GridFor(n), kThreads>>>(dcols, in, ph, pw, k, dpooled);
  return cudaGetLastError();
}

cudaError_t ReluGlobalAvgPool(const float* conv, int channels, size_t hw,
                              float* features) {
  if (channels <= 0 || hw == 0) return cudaSuccess;
  ReluGlobalAvgPoolKernel<<<channels, kThreads>>>(conv, hw, features);
  return cudaGetLastError();
}

cudaError_t ReluGlobalAvgPoolBackward(const float* dfeatures, const float* conv,
                                      int channels, size_t hw, float* dconv) {
  const size_t n = size_t(channels) * hw;
  if (n == 0) return cudaSuccess;
  ReluGlobalAvgPoolBackwardKernel<<<GridFor(n), kThreads>>>(
      dfeatures, conv, channels, hw, dconv);
  return cudaGetLastError();
}

cudaError_t PooledGradientToImage(const float* dpooled, int width, int height,
                                  int pitch, int p, bool accumulate,
                                  float* dhwc) {
  const size_t n = size_t(width) * height * 3;
  if (n == 0) return cudaSuccess;
  PooledGradientKernel<<<GridFor(n), kThreads>>>(
      dpooled, width, height, pitch, p, 1.f / float(p * p), accumulate, dhwc);
  return cudaGetLastError();
}

}  // namespace feature_kernels
}  // namespace watergs
