// Forward blending. Each tile keeps its 256 pixels' state in stack arrays
// (no heap allocation per pixel; the 8-bit composite keeps its list in a
// per-thread vector reused across tiles) and walks its splat list once; the
// inner loop runs across a 16-pixel row so it maps onto one AVX-512 vector.
#include "gaussian/rasterize_forward.h"

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <utility>
#include <vector>

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

// Another renderer's alpha at Gaussian falloff G = exp(power): 0 beyond
// power -4 (d^2 = 8), and PlayCanvas' renormalised (G - e^-4) / (1 - e^-4).
template <Falloff kFalloff>
inline RowF FalloffAlpha(float opacity, const RowFalloff& f) {
  if constexpr (kFalloff == Falloff::kInria) {
    return opacity * f.G;
  } else {
    constexpr float kEdge = 0.018315638888734f;  // e^-4
    const RowF g = kFalloff == Falloff::kNormalized
                       ? (f.G - kEdge) * (1.f / (1.f - kEdge))
                       : f.G;
    return f.power >= -4.f ? opacity * g : RowF{};
  }
}

// One contribution kept for the back-to-front composite: the tile pixel
// (row * 16 + column), the splat's index, its alpha there.
struct Contribution {
  uint32_t pixel, splat;
  float alpha;
};

// This thread's list of a tile's contributions (reused across tiles).
std::vector<Contribution>& TileContributions() {
  thread_local std::vector<Contribution> contributions;
  return contributions;
}

// A value in [0, 1] stored in an 8-bit channel (WebGL's float to unorm
// conversion: clamp, then the nearest of 255 steps, halves up as the
// reference twin rounds them).
inline float ToUnorm8(float v) {
  return std::floor(std::clamp(v, 0.f, 1.f) * 255.f + 0.5f) * (1.f / 255.f);
}

// Composites a tile's contributions (in front-to-back order) back to front
// into 8-bit channels, as a WebGL viewer draws into its RGBA8 canvas:
// PlayCanvas blends premultiplied (ONE, ONE_MINUS_SRC_ALPHA), so colour x
// alpha is clamped to [0, 1]; gaussian-splats-3d blends (SRC_ALPHA,
// ONE_MINUS_SRC_ALPHA) with the colour clamped, the same while colours stay
// within [0, 1] as its SH-0, 8-bit base colours do. Each blend is clamped
// and rounded. Writes the composite over rgb[3][256] (which holds the
// background per pixel).
void CompositeBackToFront8(const std::vector<Splat>& splats,
                           const std::vector<Contribution>& contributions,
                           float (*rgb)[kTileSize * kTileSize]) {
  for (int ch = 0; ch < 3; ++ch) {
    for (float& v : rgb[ch]) v = ToUnorm8(v);
  }
  for (auto it = contributions.rbegin(); it != contributions.rend(); ++it) {
    const Splat& s = splats[it->splat];
    for (int ch = 0; ch < 3; ++ch) {
      float& dst = rgb[ch][it->pixel];
      const float src = std::clamp(s.color[ch] * it->alpha, 0.f, 1.f);
      dst = ToUnorm8(src + dst * (1.f - it->alpha));
    }
  }
}

// Blends one tile's list into the pixels of the tile that lie in `rect`.
// on_weight(splat index, row of alpha * T) sees every blending weight: the
// render passes a no-op (compiled away), the weight pass sums them, so both
// take the same decisions. kComposite8: the contributions found front to
// back are composited back to front in 8 bits (CompositeBackToFront8).
template <Falloff kFalloff, bool kComposite8, typename OnWeight>
void BlendTile(const std::vector<Splat>& splats, const uint32_t* list,
               uint32_t count, int tx, int ty, const PixelRect& rect,
               const std::array<float, 3>& background, ImageRGB* image,
               BlendState* state, OnWeight&& on_weight) {
  constexpr int kN = kTileSize;
  const TilePixels px = PixelsOf(tx, ty, rect);
  const int base_x = tx * kN, base_y = ty * kN;
  RowF T[kN], cr[kN], cg[kN], cb[kN];
  RowI active[kN], last[kN];
  RowF col_x;  // Pixel-centre x of each lane.
  RowI in_x;   // Lanes whose column lies in the rect.
  for (int c = 0; c < kN; ++c) {
    col_x[c] = static_cast<float>(base_x + c) + 0.5f;
    in_x[c] = base_x + c >= px.x0 && base_x + c < px.x1 ? -1 : 0;
  }
  int active_count = 0;
  for (int r = 0; r < kN; ++r) {
    const bool in_y = base_y + r >= px.y0 && base_y + r < px.y1;
    T[r] = RowF{} + 1.f;
    cr[r] = cg[r] = cb[r] = RowF{};
    active[r] = in_y ? in_x : RowI{};
    last[r] = RowI{};
    active_count += in_y ? px.x1 - px.x0 : 0;
  }
  const int row_lo = px.y0 - base_y, row_hi = px.y1 - base_y;  // [lo, hi)
  std::vector<Contribution>* contributions = nullptr;
  if constexpr (kComposite8) {
    contributions = &TileContributions();
    contributions->clear();
  }
  for (uint32_t j = 0; j < count && active_count > 0; ++j) {
    const Splat& s = splats[list[j]];
    const int r0 = std::max(row_lo, s.row_min - base_y);
    const int r1 = std::min(row_hi, s.row_max - base_y + 1);
    const RowF dx = col_x - s.mean_x;
    const int contributor = static_cast<int>(j) + 1;
    RowI stopped{};
    for (int r = r0; r < r1; ++r) {
      const float dy = static_cast<float>(base_y + r) + 0.5f - s.mean_y;
      if (!RowReachesTile(s, dy, base_x)) continue;
      RowFalloff f;
      SplatRow(dx, dy, s.conic_a, s.conic_b, s.conic_c, &f);
      RowF alpha = FalloffAlpha<kFalloff>(s.opacity, f);
      alpha = alpha > kMaxAlpha ? RowF{} + kMaxAlpha : alpha;
      const RowI ok = active[r] & (f.power <= 0.f) & (alpha >= kMinAlpha);
      const RowF test_T = T[r] * (1.f - alpha);
      const RowI stop = ok & (test_T < kMinTransmittance);
      const RowI contrib = ok & ~stop;
      const RowF w = contrib ? alpha * T[r] : RowF{};
      on_weight(list[j], w);
      if constexpr (kComposite8) {
        for (int c = 0; c < kN; ++c) {
          if (contrib[c]) {
            contributions->push_back(
                {static_cast<uint32_t>(r * kN + c), list[j], alpha[c]});
          }
        }
      }
      cr[r] += w * s.color[0];
      cg[r] += w * s.color[1];
      cb[r] += w * s.color[2];
      T[r] = contrib ? test_T : T[r];
      last[r] = contrib ? RowI{} + contributor : last[r];
      active[r] &= ~stop;
      stopped -= stop;
    }
    for (int c = 0; c < kN; ++c) active_count -= stopped[c];
  }
  float composite[3][kN * kN];
  if constexpr (kComposite8) {
    for (int ch = 0; ch < 3; ++ch) {
      std::fill_n(composite[ch], kN * kN, background[ch]);
    }
    CompositeBackToFront8(splats, *contributions, composite);
  }
  const PixelRect& out = state->rect;
  for (int y = px.y0; y < px.y1; ++y) {
    for (int x = px.x0; x < px.x1; ++x) {
      const int r = y - base_y, c = x - base_x;
      const size_t k = static_cast<size_t>(y - out.y0) * out.width +
                       static_cast<size_t>(x - out.x0);
      float* rgb = image->At(x - out.x0, y - out.y0);
      if constexpr (kComposite8) {
        for (int ch = 0; ch < 3; ++ch) rgb[ch] = composite[ch][r * kN + c];
      } else {
        rgb[0] = cr[r][c] + T[r][c] * background[0];
        rgb[1] = cg[r][c] + T[r][c] * background[1];
        rgb[2] = cb[r][c] + T[r][c] * background[2];
      }
      state->final_T[k] = T[r][c];
      state->n_contrib[k] = static_cast<uint32_t>(last[r][c]);
    }
  }
}

// Calls blend(std::integral_constant<Falloff, falloff>{}): one compiled
// loop per falloff, Inria's free of the others' tests.
template <typename Blend>
void DispatchFalloff(Falloff falloff, Blend&& blend) {
  switch (falloff) {
    case Falloff::kInria:
      return blend(std::integral_constant<Falloff, Falloff::kInria>{});
    case Falloff::kCutAt8:
      return blend(std::integral_constant<Falloff, Falloff::kCutAt8>{});
    case Falloff::kNormalized:
      return blend(std::integral_constant<Falloff, Falloff::kNormalized>{});
  }
}

// Calls BlendTile with the falloff and composite of `blend` compiled in.
template <typename... Args>
void BlendTileAs(const BlendMode& blend, Args&&... args) {
  DispatchFalloff(blend.falloff, [&](auto falloff) {
    if (blend.composite_8bit) {
      BlendTile<decltype(falloff)::value, true>(std::forward<Args>(args)...);
    } else {
      BlendTile<decltype(falloff)::value, false>(std::forward<Args>(args)...);
    }
  });
}

}  // namespace

void RasterizeForward(const std::vector<Splat>& splats, const TileBins& bins,
                      const PixelRect& rect,
                      const std::array<float, 3>& background, ImageRGB* image,
                      BlendState* state, const BlendMode& blend) {
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
    BlendTileAs(blend, splats, bins.ids.data() + begin, end - begin, tx, ty,
                rect, background, image, state, [](uint32_t, const RowF&) {});
  }
}

void AccumulateSplatWeights(const std::vector<Splat>& splats,
                            const TileBins& bins, const PixelRect& rect,
                            std::vector<double>* splat_weights,
                            Falloff falloff) {
  // The blend writes an image and a state too; they are scratch here.
  ImageRGB image(rect.width, rect.height);
  BlendState state;
  state.rect = rect;
  const size_t pixels = static_cast<size_t>(rect.width) * rect.height;
  state.final_T.assign(pixels, 1.f);
  state.n_contrib.assign(pixels, 0);
  const std::array<float, 3> background = {0.f, 0.f, 0.f};
  const int range_w = bins.range.x1 - bins.range.x0;
  const int num_tiles = bins.NumTiles();
#pragma omp parallel
  {
    // Per-thread sums (a splat spans several tiles), added up below in the
    // order threads finish; in double that order moves a sum by ~1e-16 of it.
    std::vector<double> local(splats.size(), 0.0);
#pragma omp for schedule(dynamic, 1)
    for (int k = 0; k < num_tiles; ++k) {
      const int tx = bins.range.x0 + k % range_w;
      const int ty = bins.range.y0 + k / range_w;
      const uint32_t begin = bins.offsets[k], end = bins.offsets[k + 1];
      DispatchFalloff(falloff, [&](auto mode) {
        BlendTile<decltype(mode)::value, false>(
            splats, bins.ids.data() + begin, end - begin, tx, ty, rect,
            background, &image, &state,
            [&local](uint32_t splat, const RowF& w) {
              local[splat] += RowSum(w);
            });
      });
    }
#pragma omp critical
    for (size_t k = 0; k < local.size(); ++k) (*splat_weights)[k] += local[k];
  }
}

}  // namespace watergs
