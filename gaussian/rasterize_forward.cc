// Forward blending. Each tile keeps its 256 pixels' state in stack arrays
// (no heap allocation per pixel) and walks its splat list once; the inner
// loop runs across a 16-pixel row so it maps onto one AVX-512 vector.
#include "gaussian/rasterize_forward.h"

#include <algorithm>

namespace watergs {
namespace {

// Pixel bounds [x0, x1) x [y0, y1) of tile (tx, ty) inside `rect`.
struct TilePixels {
  int x0, x1, y0, y1;
};

TilePixels PixelsOf(int tx, int ty, const PixelRect& rect) {
  TilePixels p;
  p.x0 = std::max(tx * kTileSize, rect.x0);
  p.x1 = std::min(tx * kTileSize + kTileSize, rect.x0 + rect.width);
  p.y0 = std::max(ty * kTileSize, rect.y0);
  p.y1 = std::min(ty * kTileSize + kTileSize, rect.y0 + rect.height);
  return p;
}

// Blends one tile's list into the pixels of the tile that lie in `rect`.
void BlendTile(const std::vector<Splat>& splats, const uint32_t* list,
               uint32_t count, int tx, int ty, const PixelRect& rect,
               const std::array<float, 3>& background, ImageRGB* image,
               BlendState* state) {
  constexpr int kN = kTileSize;
  const TilePixels px = PixelsOf(tx, ty, rect);
  const int base_x = tx * kN, base_y = ty * kN;
  alignas(64) float T[kN][kN], cr[kN][kN], cg[kN][kN], cb[kN][kN];
  alignas(64) float active[kN][kN];
  alignas(64) int last[kN][kN];
  int active_count = 0;
  for (int r = 0; r < kN; ++r) {
    for (int c = 0; c < kN; ++c) {
      const int x = base_x + c, y = base_y + r;
      const bool in = x >= px.x0 && x < px.x1 && y >= px.y0 && y < px.y1;
      T[r][c] = 1.f, cr[r][c] = cg[r][c] = cb[r][c] = 0.f;
      active[r][c] = in ? 1.f : 0.f;
      last[r][c] = 0;
      active_count += in;
    }
  }
  const int row_lo = px.y0 - base_y, row_hi = px.y1 - base_y;  // [lo, hi)
  for (uint32_t j = 0; j < count && active_count > 0; ++j) {
    const Splat& s = splats[list[j]];
    const int r0 = std::max(row_lo, s.row_min - base_y);
    const int r1 = std::min(row_hi, s.row_max - base_y + 1);
    const int contributor = static_cast<int>(j) + 1;
    int stopped = 0;
    for (int r = r0; r < r1; ++r) {
      const float dy = static_cast<float>(base_y + r) + 0.5f - s.mean_y;
#pragma omp simd reduction(+ : stopped)
      for (int c = 0; c < kN; ++c) {
        const float dx = static_cast<float>(base_x + c) + 0.5f - s.mean_x;
        const float power =
            -0.5f * (s.conic_a * dx * dx + s.conic_c * dy * dy) -
            s.conic_b * dx * dy;
        const float alpha = std::min(kMaxAlpha, s.opacity * FastExp(power));
        const bool ok =
            active[r][c] > 0.f && power <= 0.f && alpha >= kMinAlpha;
        const float test_T = T[r][c] * (1.f - alpha);
        const bool stop = ok && test_T < kMinTransmittance;
        const bool contrib = ok && !stop;
        const float w = contrib ? alpha * T[r][c] : 0.f;
        cr[r][c] += w * s.color[0];
        cg[r][c] += w * s.color[1];
        cb[r][c] += w * s.color[2];
        T[r][c] = contrib ? test_T : T[r][c];
        last[r][c] = contrib ? contributor : last[r][c];
        active[r][c] = stop ? 0.f : active[r][c];
        stopped += stop ? 1 : 0;
      }
    }
    active_count -= stopped;
  }
  const PixelRect& out = state->rect;
  for (int y = px.y0; y < px.y1; ++y) {
    for (int x = px.x0; x < px.x1; ++x) {
      const int r = y - base_y, c = x - base_x;
      const size_t k = static_cast<size_t>(y - out.y0) * out.width +
                       static_cast<size_t>(x - out.x0);
      float* rgb = image->At(x - out.x0, y - out.y0);
      rgb[0] = cr[r][c] + T[r][c] * background[0];
      rgb[1] = cg[r][c] + T[r][c] * background[1];
      rgb[2] = cb[r][c] + T[r][c] * background[2];
      state->final_T[k] = T[r][c];
      state->n_contrib[k] = static_cast<uint32_t>(last[r][c]);
    }
  }
}

}  // namespace

void RasterizeForward(const std::vector<Splat>& splats, const TileBins& bins,
                      const PixelRect& rect,
                      const std::array<float, 3>& background, ImageRGB* image,
                      BlendState* state) {
  *image = ImageRGB(rect.width, rect.height);
  state->rect = rect;
  const size_t pixels = static_cast<size_t>(rect.width) * rect.height;
  state->final_T.assign(pixels, 1.f);
  state->n_contrib.assign(pixels, 0);
  const int range_w = bins.range.x1 - bins.range.x0;
  const int num_tiles = bins.NumTiles();
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < num_tiles; ++k) {
    const int tx = bins.range.x0 + k % range_w;
    const int ty = bins.range.y0 + k / range_w;
    const uint32_t begin = bins.offsets[k], end = bins.offsets[k + 1];
    BlendTile(splats, bins.ids.data() + begin, end - begin, tx, ty, rect,
              background, image, state);
  }
}

}  // namespace watergs
