// Front-to-back alpha blending of depth-sorted splats over 16 x 16 tiles
// (Inria semantics), parallel over tiles with OpenMP, SIMD across the 16
// pixels of a tile row.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "gaussian/image.h"
#include "gaussian/rasterizer.h"
#include "gaussian/tile_binning.h"

namespace watergs {

// Alpha is capped here (Inria).
inline constexpr float kMaxAlpha = 0.99f;
// Contributions with alpha below this are skipped (Inria).
inline constexpr float kMinAlpha = 1.0f / 255.0f;
// A pixel stops when its transmittance would drop below this (Inria).
inline constexpr float kMinTransmittance = 1e-4f;

// One projected Gaussian as the blending loops read it: one cache line, since
// the loops vectorise over pixels and read a splat's fields together.
struct alignas(64) Splat {
  // Pixel-space mean (COLMAP convention: pixel centres at +0.5).
  float mean_x, mean_y;
  // Conic (a, b, c): power = -0.5 (a dx^2 + c dy^2) - b dx dy.
  float conic_a, conic_b, conic_c;
  // Opacity after the sigmoid.
  float opacity;
  // Clamped colour.
  float color[3];
  // Rows y (integers, full frame) where alpha can reach 1/255: [row_min,
  // row_max]; rows outside are skipped without changing the result.
  int row_min, row_max;
  // Padding to 64 bytes.
  float pad[5];
};

// Per-pixel results of a forward pass that the backward pass needs.
struct BlendState {
  // The rendered rectangle of the full frame.
  PixelRect rect;
  // Transmittance after the last contribution, rect.height x rect.width.
  std::vector<float> final_T;
  // 1 + the tile-list position of the last contributing splat (0: none).
  std::vector<uint32_t> n_contrib;
};

// Renders `rect` (inside the full frame, covered by bins.range) into `image`
// (rect-sized) and fills `state`.
void RasterizeForward(const std::vector<Splat>& splats, const TileBins& bins,
                      const PixelRect& rect,
                      const std::array<float, 3>& background, ImageRGB* image,
                      BlendState* state);

// Vectorisable exp for x <= 0 (Cephes polynomial, ~1 ulp); forward and
// backward both use it so their skip decisions agree exactly.
inline float FastExp(float x) {
  x = x < -87.0f ? -87.0f : x;
  const float n = __builtin_floorf(x * 1.44269504088896341f + 0.5f);
  float r = x - n * 0.693359375f;
  r = r - n * -2.12194440e-4f;
  float p = 1.9875691500e-4f;
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * r * r + r + 1.0f;
  const int bits = (static_cast<int>(n) + 127) << 23;
  return p * __builtin_bit_cast(float, bits);
}

}  // namespace watergs
