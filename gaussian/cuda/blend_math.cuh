// Device helpers shared by the CUDA forward and backward blending kernels,
// one pixel at a time: the same expressions as the CPU's row-vector helpers
// (RowExp, SplatRow, RowReachesTile in rasterize_forward.h), so both sides
// make the same skip decisions up to float rounding.
#pragma once

#include <cuda_runtime.h>

#include "gaussian/cuda/raster_kernels.h"

namespace watergs::cuda_raster {

// Inria's blending constants (rasterize_forward.h).
constexpr float kMaxAlpha = 0.99f;
constexpr float kMinAlpha = 1.0f / 255.0f;
constexpr float kMinTransmittance = 1e-4f;
constexpr float kMinPower = -20.0f;

// exp(x) for kMinPower <= x <= 0: the CPU's Cephes polynomial (RowExp), not
// CUDA's expf, so that G differs from the CPU's by rounding only (not bit
// for bit: nvcc and GCC both contract multiply-adds into FMAs, at different
// places).
__device__ inline float CephesExp(float x) {
  const float t = x * 1.44269504088896341f + 0.5f;
  int n = static_cast<int>(t);
  if (static_cast<float>(n) > t) --n;  // Truncation -> floor.
  const float nf = static_cast<float>(n);
  float r = x - nf * 0.693359375f;
  r = r - nf * -2.12194440e-4f;
  float p = r * 1.9875691500e-4f + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * r * r + r + 1.0f;
  return p * __int_as_float((n + 127) << 23);
}

// Power (<= 0 for a valid conic) of splat s at offset (dx, dy) from its mean,
// and the falloff G = exp(max(power, kMinPower)) (SplatRow).
__device__ inline void Falloff(const DeviceSplat& s, float dx, float dy,
                               float* power, float* G) {
  *power =
      -0.5f * (s.conic_a * dx * dx + s.conic_c * dy * dy) - s.conic_b * dx * dy;
  *G = CephesExp(*power < kMinPower ? kMinPower : *power);
}

// Whether splat s can reach alpha 1/255 on pixel row y (full frame) in the
// tile whose first column is base_x: the CPU's row bounds and
// RowReachesTile, which skip work without changing the result.
__device__ inline bool RowReaches(const DeviceSplat& s, int y, float dy,
                                  int base_x) {
  if (y < s.row_min || y > s.row_max) return false;
  const float h2 = s.reach - dy * dy * s.narrowing;
  if (!(h2 >= 0.f)) return false;
  const float half = sqrtf(h2) * 1.001f + 0.5f;
  const float center = s.mean_x + s.shear * dy;
  return center + half >= static_cast<float>(base_x) + 0.5f &&
         center - half <= static_cast<float>(base_x + kTile) - 0.5f;
}

}  // namespace watergs::cuda_raster
