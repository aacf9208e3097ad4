// CUDA backward blending, the GPU form of rasterize_backward.cc: one 16 x 16
// thread block per tile, each pixel walking the tile's list back to front
// from the block's last contributor (Inria's recurrence, transmittance
// recovered by division, the 0.99 alpha cap differentiated exactly as the
// CPU does). A warp's 32 pixels reduce each splat's gradient with shuffles
// before one atomicAdd per warp into the splat's per-Gaussian slot.
#include <cuda_runtime.h>

#include <cstdint>

#include "gaussian/cuda/blend_math.cuh"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/raster_kernels.h"

namespace watergs::cuda_raster {
namespace {

// Background colour passed by value.
struct Rgb {
  float v[3];
};

// Gradient fields of DeviceSplatGrad as an array, in its order.
constexpr int kGradFields = 9;

// Per-pixel state of the reverse walk (TileState of the CPU, one lane).
struct PixelState {
  // Transmittance before the current splat, and after the last contributor.
  float T, T_final;
  // dL/d(pixel colour) and background . dL/d(pixel colour).
  float dpix[3], bg_dot;
  // Colour blended behind the current splat, Inria's recurrence.
  float accum[3], last_color[3], last_alpha;
  // 1 + list position of the last contributor (0: none).
  uint32_t last;
};

// One splat at one pixel, back to front (the CPU's BackwardRow for one
// lane); returns false (and leaves the state) if it did not contribute.
__device__ bool BackwardPixel(const DeviceSplat& s, float dx, float dy,
                              PixelState* st, float* grad) {
  float power, G;
  Falloff(s, dx, dy, &power, &G);
  const float raw = s.opacity * G;
  const float alpha = raw > kMaxAlpha ? kMaxAlpha : raw;
  if (!(power <= 0.f) || !(alpha >= kMinAlpha)) return false;
  const float inv_one_minus = 1.f / (1.f - alpha);
  const float T = st->T * inv_one_minus;
  const float w = alpha * T;
  const float la = st->last_alpha;
  float dL_dalpha = 0.f;
  for (int ch = 0; ch < 3; ++ch) {
    const float acc = la * st->last_color[ch] + (1.f - la) * st->accum[ch];
    dL_dalpha += (s.color[ch] - acc) * st->dpix[ch];
    st->accum[ch] = acc;
    st->last_color[ch] = s.color[ch];
    grad[6 + ch] = w * st->dpix[ch];
  }
  dL_dalpha = dL_dalpha * T - st->T_final * inv_one_minus * st->bg_dot;
  st->T = T;
  st->last_alpha = alpha;
  // The 0.99 cap has zero slope where it binds.
  const float dL_draw = raw < kMaxAlpha ? dL_dalpha : 0.f;
  const float dL_dpower = dL_draw * raw;
  // power = -0.5 (a dx^2 + c dy^2) - b dx dy with dx = x - mean_x.
  const float p_x = dL_dpower * dx, p_y = dL_dpower * dy;
  grad[0] = s.conic_a * p_x + s.conic_b * p_y;
  grad[1] = s.conic_c * p_y + s.conic_b * p_x;
  grad[2] = -0.5f * (p_x * dx);
  grad[3] = -(p_x * dy);
  grad[4] = -0.5f * (dL_dpower * (dy * dy));
  grad[5] = G * dL_draw;
  return true;
}

// Sums grad over the warp and adds it to `out` from lane 0.
__device__ void WarpAtomicAdd(float* grad, DeviceSplatGrad* out) {
  for (int offset = 16; offset > 0; offset /= 2) {
    for (int f = 0; f < kGradFields; ++f) {
      grad[f] += __shfl_down_sync(0xffffffffu, grad[f], offset);
    }
  }
  if ((threadIdx.x + threadIdx.y * kTile) % 32 != 0) return;
  atomicAdd(&out->mean_x, grad[0]);
  atomicAdd(&out->mean_y, grad[1]);
  atomicAdd(&out->conic_a, grad[2]);
  atomicAdd(&out->conic_b, grad[3]);
  atomicAdd(&out->conic_c, grad[4]);
  atomicAdd(&out->opacity, grad[5]);
  for (int ch = 0; ch < 3; ++ch) atomicAdd(&out->color[ch], grad[6 + ch]);
}

__global__ void __launch_bounds__(kBatch)
    BackwardKernel(const DeviceSplat* splats, const uint32_t* sorted_ids,
                   const uint32_t* ranges, TileRect render_tiles, PixelBox rect,
                   Rgb background, const float* final_T,
                   const uint32_t* n_contrib, const float* grad_image,
                   DeviceSplatGrad* splat_grads) {
  __shared__ DeviceSplat batch[kBatch];
  __shared__ uint32_t batch_ids[kBatch];
  __shared__ int block_last;
  const int tile = blockIdx.y * gridDim.x + blockIdx.x;
  const int base_x = (render_tiles.x0 + static_cast<int>(blockIdx.x)) * kTile;
  const int base_y = (render_tiles.y0 + static_cast<int>(blockIdx.y)) * kTile;
  const int x = base_x + static_cast<int>(threadIdx.x);
  const int y = base_y + static_cast<int>(threadIdx.y);
  const int rank = threadIdx.y * kTile + threadIdx.x;
  const bool inside = x >= rect.x0 && x < rect.x0 + rect.width &&
                      y >= rect.y0 && y < rect.y0 + rect.height;
  const uint32_t begin = ranges[2 * tile];
  PixelState st{};
  st.T_final = 1.f;
  if (inside) {
    const size_t k = static_cast<size_t>(y - rect.y0) * rect.width +
                     static_cast<size_t>(x - rect.x0);
    st.T_final = final_T[k];
    st.last = n_contrib[k];
    for (int ch = 0; ch < 3; ++ch) st.dpix[ch] = grad_image[3 * k + ch];
  }
  st.T = st.T_final;
  st.bg_dot = background.v[0] * st.dpix[0] + background.v[1] * st.dpix[1] +
              background.v[2] * st.dpix[2];
  if (rank == 0) block_last = 0;
  __syncthreads();
  atomicMax(&block_last, static_cast<int>(st.last));
  __syncthreads();
  const float px = static_cast<float>(x) + 0.5f;
  const float py = static_cast<float>(y) + 0.5f;
  for (int batch_end = block_last; batch_end > 0; batch_end -= kBatch) {
    const int batch_start = max(0, batch_end - kBatch);
    __syncthreads();  // The previous batch is no longer read.
    if (batch_end - 1 - rank >= batch_start) {
      const uint32_t id = sorted_ids[begin + batch_end - 1 - rank];
      batch_ids[rank] = id;
      batch[rank] = splats[id];
    }
    __syncthreads();
    for (int k = 0; k < batch_end - batch_start; ++k) {
      const int j = batch_end - 1 - k;  // List position, back to front.
      const DeviceSplat& s = batch[k];
      float grad[kGradFields] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
      const float dy = py - s.mean_y;
      const bool valid = j < static_cast<int>(st.last) &&
                         RowReaches(s, y, dy, base_x) &&
                         BackwardPixel(s, px - s.mean_x, dy, &st, grad);
      if (__any_sync(0xffffffffu, valid)) {
        WarpAtomicAdd(grad, &splat_grads[batch_ids[k]]);
      }
    }
  }
}

}  // namespace

void LaunchRasterizeBackward(const DeviceSplat* splats,
                             const uint32_t* sorted_ids, const uint32_t* ranges,
                             TileRect render_tiles, PixelBox rect,
                             const float* background, const float* final_T,
                             const uint32_t* n_contrib, const float* grad_image,
                             DeviceSplatGrad* splat_grads) {
  const int range_w = render_tiles.x1 - render_tiles.x0;
  const int range_h = render_tiles.y1 - render_tiles.y0;
  if (range_w <= 0 || range_h <= 0) return;
  const Rgb bg{{background[0], background[1], background[2]}};
  BackwardKernel<<<dim3(range_w, range_h), dim3(kTile, kTile)>>>(
      splats, sorted_ids, ranges, render_tiles, rect, bg, final_T, n_contrib,
      grad_image, splat_grads);
  WATERGS_CUDA_CHECK_LAUNCH();
}

}  // namespace watergs::cuda_raster
