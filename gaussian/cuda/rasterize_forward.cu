// CUDA forward blending, the GPU form of rasterize_forward.cc: one 16 x 16
// thread block per tile of the rendered range, one thread per pixel; the
// tile's depth-ordered list is staged through shared memory in batches of
// 256 splats (one load per thread), and each pixel blends front to back
// with Inria's rules exactly as the CPU's BlendTile does per lane.
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

__global__ void __launch_bounds__(kBatch)
    ForwardKernel(const DeviceSplat* splats, const uint32_t* sorted_ids,
                  const uint32_t* ranges, TileRect render_tiles, PixelBox rect,
                  Rgb background, float* image, float* final_T,
                  uint32_t* n_contrib) {
  __shared__ DeviceSplat batch[kBatch];
  const int tile = blockIdx.y * gridDim.x + blockIdx.x;
  const int base_x = (render_tiles.x0 + static_cast<int>(blockIdx.x)) * kTile;
  const int base_y = (render_tiles.y0 + static_cast<int>(blockIdx.y)) * kTile;
  const int x = base_x + static_cast<int>(threadIdx.x);
  const int y = base_y + static_cast<int>(threadIdx.y);
  const int rank = threadIdx.y * kTile + threadIdx.x;
  const bool inside = x >= rect.x0 && x < rect.x0 + rect.width &&
                      y >= rect.y0 && y < rect.y0 + rect.height;
  const uint32_t begin = ranges[2 * tile];
  const int count = static_cast<int>(ranges[2 * tile + 1] - begin);
  // Pixel centre (COLMAP convention), as the CPU's col_x and row offset.
  const float px = static_cast<float>(x) + 0.5f;
  const float py = static_cast<float>(y) + 0.5f;
  float T = 1.f, color[3] = {0.f, 0.f, 0.f};
  uint32_t last = 0;
  bool done = !inside;
  for (int start = 0; start < count; start += kBatch) {
    // Every pixel finished: the rest of the list cannot change the tile.
    if (__syncthreads_count(done) == kBatch) break;
    if (start + rank < count) {
      batch[rank] = splats[sorted_ids[begin + start + rank]];
    }
    __syncthreads();
    const int batch_count = min(kBatch, count - start);
    for (int k = 0; !done && k < batch_count; ++k) {
      const DeviceSplat& s = batch[k];
      const float dy = py - s.mean_y;
      if (!RowReaches(s, y, dy, base_x)) continue;
      float power, G;
      Falloff(s, px - s.mean_x, dy, &power, &G);
      float alpha = s.opacity * G;
      alpha = alpha > kMaxAlpha ? kMaxAlpha : alpha;
      if (!(power <= 0.f) || !(alpha >= kMinAlpha)) continue;
      const float test_T = T * (1.f - alpha);
      if (test_T < kMinTransmittance) {
        done = true;
        break;
      }
      const float w = alpha * T;
      for (int ch = 0; ch < 3; ++ch) color[ch] += w * s.color[ch];
      T = test_T;
      last = static_cast<uint32_t>(start + k + 1);
    }
  }
  if (!inside) return;
  const size_t k = static_cast<size_t>(y - rect.y0) * rect.width +
                   static_cast<size_t>(x - rect.x0);
  for (int ch = 0; ch < 3; ++ch) {
    image[3 * k + ch] = color[ch] + T * background.v[ch];
  }
  final_T[k] = T;
  n_contrib[k] = last;
}

}  // namespace

void LaunchRasterizeForward(const DeviceSplat* splats,
                            const uint32_t* sorted_ids, const uint32_t* ranges,
                            TileRect render_tiles, PixelBox rect,
                            const float* background, float* image,
                            float* final_T, uint32_t* n_contrib) {
  const int range_w = render_tiles.x1 - render_tiles.x0;
  const int range_h = render_tiles.y1 - render_tiles.y0;
  if (range_w <= 0 || range_h <= 0) return;
  const Rgb bg{{background[0], background[1], background[2]}};
  ForwardKernel<<<dim3(range_w, range_h), dim3(kTile, kTile)>>>(
      splats, sorted_ids, ranges, render_tiles, rect, bg, image, final_T,
      n_contrib);
  WATERGS_CUDA_CHECK_LAUNCH();
}

}  // namespace watergs::cuda_raster
