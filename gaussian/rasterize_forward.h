// Front-to-back alpha blending of depth-sorted splats over 16 x 16 tiles
// (Inria semantics; a web viewer's 8-bit back-to-front composite of the
// same contributions on request), parallel over tiles with OpenMP, SIMD
// across the 16 pixels of a tile row.
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

// exp is evaluated at max(power, kMinPower): below it alpha < 1e-8 < 1/255
// whatever the opacity, so no decision changes, and no denormal (slow on
// this CPU) is ever produced.
inline constexpr float kMinPower = -20.0f;

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
  // On the row at dy from the mean, alpha can reach 1/255 only for
  // |x - (mean_x + shear * dy)| <= sqrt(reach - dy^2 * narrowing) (slightly
  // widened); rows whose interval misses a tile are skipped there.
  float shear, reach, narrowing;
  // Padding to 64 bytes.
  float pad[2];
};

// Whether the splat's alpha can reach 1/255 somewhere on the tile row at
// offset dy, columns [base_x, base_x + 16).
inline bool RowReachesTile(const Splat& s, float dy, int base_x) {
  const float h2 = s.reach - dy * dy * s.narrowing;
  if (!(h2 >= 0.f)) return false;
  const float half = __builtin_sqrtf(h2) * 1.001f + 0.5f;
  const float center = s.mean_x + s.shear * dy;
  return center + half >= static_cast<float>(base_x) + 0.5f &&
         center - half <= static_cast<float>(base_x + kTileSize) - 0.5f;
}

// Per-pixel results of a forward pass that the backward pass needs.
struct BlendState {
  // The rendered rectangle of the full frame.
  PixelRect rect;
  // Transmittance after the last contribution, rect.height x rect.width.
  std::vector<float> final_T;
  // 1 + the tile-list position of the last contributing splat (0: none).
  std::vector<uint32_t> n_contrib;
};

// How the forward pass blends: the alpha falloff, and whether the pixel is
// composited back to front in 8 bits instead of Inria's float sum front to
// back (another renderer's conventions, render_conventions.h).
struct BlendMode {
  Falloff falloff = Falloff::kInria;
  bool composite_8bit = false;
};

// Renders `rect` (inside the full frame, covered by bins.range) into `image`
// (rect-sized) and fills `state` (the front-to-back pass's, whatever the
// composite).
void RasterizeForward(const std::vector<Splat>& splats, const TileBins& bins,
                      const PixelRect& rect,
                      const std::array<float, 3>& background, ImageRGB* image,
                      BlendState* state, const BlendMode& blend = {});

// Adds to (*splat_weights)[k] (one entry per splat, sized by the caller) the
// sum over `rect`'s pixels of splat k's blending weight alpha * T, with the
// forward pass's own decisions (1/255 cut-off, 0.99 cap, early stop).
void AccumulateSplatWeights(const std::vector<Splat>& splats,
                            const TileBins& bins, const PixelRect& rect,
                            std::vector<double>* splat_weights,
                            Falloff falloff = Falloff::kInria);

// One tile row of 16 floats / ints (GCC vector extension: one AVX-512
// register here, split into narrower registers on other targets). Written
// explicitly because the compiler will not if-convert the blending loop
// under the default trapping-math rules.
using RowF = float __attribute__((vector_size(4 * kTileSize)));
using RowI = int32_t __attribute__((vector_size(4 * kTileSize)));

// exp for a row of x <= 0 (Cephes polynomial, ~1 ulp). Vectors go by
// pointer: by value they would change the ABI when AVX-512 is off.
inline void RowExp(const RowF& x, RowF* out) {
  const RowF t = x * 1.44269504088896341f + 0.5f;
  RowI n = __builtin_convertvector(t, RowI);
  n += __builtin_convertvector(n, RowF) > t;  // Truncation -> floor.
  const RowF nf = __builtin_convertvector(n, RowF);
  RowF r = x - nf * 0.693359375f;
  r = r - nf * -2.12194440e-4f;
  RowF p = r * 1.9875691500e-4f + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * r * r + r + 1.0f;
  *out = p * reinterpret_cast<RowF>((n + 127) << 23);
}

// Gaussian falloff of one splat over a tile row: power (<= 0 for a valid
// conic) and G = exp(max(power, kMinPower)). Forward and backward both call
// this, so their skip decisions agree bit for bit.
struct RowFalloff {
  RowF power, G;
};
inline void SplatRow(const RowF& dx, float dy, float conic_a, float conic_b,
                     float conic_c, RowFalloff* f) {
  f->power =
      -0.5f * (conic_a * dx * dx + conic_c * dy * dy) - conic_b * dx * dy;
  RowExp(f->power < kMinPower ? RowF{} + kMinPower : f->power, &f->G);
}

// Sum of a row's lanes, as a tree of half-width adds (a serial chain of 16
// scalar adds costs more than the row arithmetic it reduces).
inline float RowSum(const RowF& v) {
  using F8 = float __attribute__((vector_size(32)));
  using F4 = float __attribute__((vector_size(16)));
  const F8 a = __builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7) +
               __builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15);
  const F4 b = __builtin_shufflevector(a, a, 0, 1, 2, 3) +
               __builtin_shufflevector(a, a, 4, 5, 6, 7);
  return (b[0] + b[2]) + (b[1] + b[3]);
}

}  // namespace watergs
