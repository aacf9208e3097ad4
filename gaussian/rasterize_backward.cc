// Backward blending. Walks each tile's list from the last contributor back
// to the front, recovering each pixel's transmittance by division (Inria),
// with per-pixel state in stack arrays and the 16-pixel row loop vectorised.
#include "gaussian/rasterize_backward.h"

#include <algorithm>

namespace watergs {
namespace {

constexpr int kN = kTileSize;

// Per-pixel state of the backward walk for one tile, one RowF per row.
struct TileState {
  RowF T[kN], T_final[kN], dpix[3][kN], bg_dot[kN];
  RowF accum[3][kN], last_color[3][kN], last_alpha[kN];
  RowI last[kN];
};

// Loads final transmittance, contributor counts and dL/dpixel of the tile's
// pixels inside the rect; returns the largest contributor count.
int LoadTile(int tx, int ty, const std::array<float, 3>& bg,
             const BlendState& state, const ImageRGB& grad_image,
             TileState* st) {
  const PixelRect& rect = state.rect;
  int max_last = 0;
  for (int r = 0; r < kN; ++r) {
    for (int c = 0; c < kN; ++c) {
      const int x = tx * kN + c, y = ty * kN + r;
      const bool in = x >= rect.x0 && x < rect.x0 + rect.width &&
                      y >= rect.y0 && y < rect.y0 + rect.height;
      float g[3] = {0, 0, 0}, T = 1.f;
      int last = 0;
      if (in) {
        const size_t k = static_cast<size_t>(y - rect.y0) * rect.width +
                         static_cast<size_t>(x - rect.x0);
        const float* d = grad_image.At(x - rect.x0, y - rect.y0);
        g[0] = d[0], g[1] = d[1], g[2] = d[2];
        T = state.final_T[k];
        last = static_cast<int>(state.n_contrib[k]);
      }
      st->T[r][c] = st->T_final[r][c] = T;
      for (int ch = 0; ch < 3; ++ch) st->dpix[ch][r][c] = g[ch];
      st->bg_dot[r][c] = bg[0] * g[0] + bg[1] * g[1] + bg[2] * g[2];
      st->last[r][c] = last;
      max_last = std::max(max_last, last);
    }
    for (int ch = 0; ch < 3; ++ch) {
      st->accum[ch][r] = st->last_color[ch][r] = RowF{};
    }
    st->last_alpha[r] = RowF{};
  }
  return max_last;
}

// Gradient sums of one splat over a tile, one lane per column. With
// P = dL/dpower: p_y = sum P dy, p_yy = sum P dy^2, p_x = sum P dx,
// p_xy = sum P dx dy, p_xx = sum P dx^2; the mean and conic gradients are
// combinations of these, formed once per splat instead of per row.
struct RowGrads {
  RowF p_y{}, p_yy{}, p_x{}, p_xy{}, p_xx{}, op{}, rgb[3] = {};
};

// One splat over one tile row, back to front (Inria's recurrence).
inline void BackwardRow(const Splat& s, int j, const RowF& dx, float dy, int r,
                        TileState* st, RowGrads* g) {
  RowFalloff f;
  SplatRow(dx, dy, s.conic_a, s.conic_b, s.conic_c, &f);
  const RowF raw = s.opacity * f.G;
  const RowF alpha = raw > kMaxAlpha ? RowF{} + kMaxAlpha : raw;
  const RowI valid =
      (RowI{} + j < st->last[r]) & (f.power <= 0.f) & (alpha >= kMinAlpha);
  const RowF inv_one_minus = 1.f / (1.f - alpha);
  const RowF T = valid ? st->T[r] * inv_one_minus : st->T[r];
  const RowF w = valid ? alpha * T : RowF{};
  const RowF la = st->last_alpha[r];
  RowF dL_dalpha{};
  for (int ch = 0; ch < 3; ++ch) {
    const RowF acc = la * st->last_color[ch][r] + (1.f - la) * st->accum[ch][r];
    dL_dalpha += (s.color[ch] - acc) * st->dpix[ch][r];
    st->accum[ch][r] = valid ? acc : st->accum[ch][r];
    st->last_color[ch][r] =
        valid ? RowF{} + s.color[ch] : st->last_color[ch][r];
    g->rgb[ch] += w * st->dpix[ch][r];
  }
  dL_dalpha = dL_dalpha * T - st->T_final[r] * inv_one_minus * st->bg_dot[r];
  st->T[r] = T;
  st->last_alpha[r] = valid ? alpha : la;
  // The 0.99 cap has zero slope where it binds.
  const RowF dL_draw = valid & (raw < kMaxAlpha) ? dL_dalpha : RowF{};
  const RowF dL_dpower = dL_draw * raw;
  g->op += f.G * dL_draw;
  const RowF px = dL_dpower * dx;
  g->p_y += dL_dpower * dy;
  g->p_yy += dL_dpower * (dy * dy);
  g->p_x += px;
  g->p_xy += px * dy;
  g->p_xx += px * dx;
}

// Walks one tile back to front; out[j] receives the gradient of list entry j
// (entries that never contribute keep their zero).
void BackwardTile(const std::vector<Splat>& splats, const uint32_t* list,
                  int tx, int ty, const std::array<float, 3>& bg,
                  const BlendState& state, const ImageRGB& grad_image,
                  TileState* st, SplatGrad* out) {
  const int max_last = LoadTile(tx, ty, bg, state, grad_image, st);
  const int base_x = tx * kN, base_y = ty * kN;
  const int row_lo = std::max(0, state.rect.y0 - base_y);
  const int row_hi = std::min(kN, state.rect.y0 + state.rect.height - base_y);
  RowF col_x;
  for (int c = 0; c < kN; ++c) col_x[c] = static_cast<float>(base_x + c) + 0.5f;
  for (int j = max_last - 1; j >= 0; --j) {
    const Splat& s = splats[list[j]];
    const int r0 = std::max(row_lo, s.row_min - base_y);
    const int r1 = std::min(row_hi, s.row_max - base_y + 1);
    if (r0 >= r1) continue;
    const RowF dx = col_x - s.mean_x;
    RowGrads g;
    for (int r = r0; r < r1; ++r) {
      const float dy = static_cast<float>(base_y + r) + 0.5f - s.mean_y;
      if (!RowReachesTile(s, dy, base_x)) continue;
      BackwardRow(s, j, dx, dy, r, st, &g);
    }
    SplatGrad& o = out[j];
    // power = -0.5 (a dx^2 + c dy^2) - b dx dy, dx = x - mean_x.
    const float p_y = RowSum(g.p_y), p_x = RowSum(g.p_x);
    o.mean_x = s.conic_a * p_x + s.conic_b * p_y;
    o.mean_y = s.conic_c * p_y + s.conic_b * p_x;
    o.conic_a = -0.5f * RowSum(g.p_xx);
    o.conic_b = -RowSum(g.p_xy);
    o.conic_c = -0.5f * RowSum(g.p_yy);
    o.opacity = RowSum(g.op);
    for (int ch = 0; ch < 3; ++ch) o.color[ch] = RowSum(g.rgb[ch]);
  }
}

}  // namespace

void RasterizeBackward(const std::vector<Splat>& splats, const TileBins& bins,
                       const std::array<float, 3>& background,
                       const BlendState& state, const ImageRGB& grad_image,
                       std::vector<SplatGrad>* grads) {
  // One gradient slot per (tile, splat) entry: tiles can then be scheduled
  // dynamically, and the per-splat sums below run in a fixed order, so the
  // result does not depend on timing or on the thread count.
  std::vector<SplatGrad> entry_grads(bins.ids.size());
  const int range_w = bins.range.x1 - bins.range.x0;
  const int num_tiles = bins.NumTiles();
#pragma omp parallel
  {
    TileState st;
#pragma omp for schedule(dynamic, 1)
    for (int k = 0; k < num_tiles; ++k) {
      const int tx = bins.range.x0 + k % range_w;
      const int ty = bins.range.y0 + k / range_w;
      BackwardTile(splats, bins.ids.data() + bins.offsets[k], tx, ty,
                   background, state, grad_image, &st,
                   entry_grads.data() + bins.offsets[k]);
    }
  }
  const size_t n = splats.size();
  grads->assign(n, SplatGrad());
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < n; ++i) {
    SplatGrad& g = (*grads)[i];
    for (uint32_t e = bins.splat_offsets[i]; e < bins.splat_offsets[i + 1];
         ++e) {
      const SplatGrad& b = entry_grads[bins.entries[e]];
      g.mean_x += b.mean_x, g.mean_y += b.mean_y;
      g.conic_a += b.conic_a, g.conic_b += b.conic_b, g.conic_c += b.conic_c;
      g.opacity += b.opacity;
      for (int ch = 0; ch < 3; ++ch) g.color[ch] += b.color[ch];
    }
  }
}

}  // namespace watergs
