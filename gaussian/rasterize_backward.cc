// Backward blending. Walks each tile's list from the last contributor back
// to the front, recovering each pixel's transmittance by division (Inria),
// with per-pixel state in stack arrays and the 16-pixel row loop vectorised.
#include "gaussian/rasterize_backward.h"

#include <omp.h>

#include <algorithm>

namespace watergs {
namespace {

constexpr int kN = kTileSize;

// Per-pixel state of the backward walk for one tile.
struct TileState {
  alignas(64) float T[kN][kN];
  alignas(64) float T_final[kN][kN];
  alignas(64) float dpix[3][kN][kN];
  alignas(64) float bg_dot[kN][kN];
  alignas(64) float accum[3][kN][kN];
  alignas(64) float last_color[3][kN][kN];
  alignas(64) float last_alpha[kN][kN];
  alignas(64) int last[kN][kN];
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
      for (int ch = 0; ch < 3; ++ch) {
        st->dpix[ch][r][c] = g[ch];
        st->accum[ch][r][c] = st->last_color[ch][r][c] = 0.f;
      }
      st->bg_dot[r][c] = bg[0] * g[0] + bg[1] * g[1] + bg[2] * g[2];
      st->last_alpha[r][c] = 0.f;
      st->last[r][c] = last;
      max_last = std::max(max_last, last);
    }
  }
  return max_last;
}

// Walks one tile back to front, adding splat gradients into `out`.
void BackwardTile(const std::vector<Splat>& splats, const uint32_t* list,
                  int tx, int ty, const std::array<float, 3>& bg,
                  const BlendState& state, const ImageRGB& grad_image,
                  TileState* st, SplatGrad* out) {
  const int max_last = LoadTile(tx, ty, bg, state, grad_image, st);
  const int base_x = tx * kN, base_y = ty * kN;
  const int row_lo = std::max(0, state.rect.y0 - base_y);
  const int row_hi = std::min(kN, state.rect.y0 + state.rect.height - base_y);
  for (int j = max_last - 1; j >= 0; --j) {
    const Splat& s = splats[list[j]];
    const int r0 = std::max(row_lo, s.row_min - base_y);
    const int r1 = std::min(row_hi, s.row_max - base_y + 1);
    float g_mx = 0, g_my = 0, g_a = 0, g_b = 0, g_c = 0, g_op = 0;
    float g_r = 0, g_g = 0, g_bl = 0;
    for (int r = r0; r < r1; ++r) {
      const float dy = static_cast<float>(base_y + r) + 0.5f - s.mean_y;
#pragma omp simd reduction(+ : g_mx, g_my, g_a, g_b, g_c, g_op, g_r, g_g, g_bl)
      for (int c = 0; c < kN; ++c) {
        const float dx = static_cast<float>(base_x + c) + 0.5f - s.mean_x;
        const float power =
            -0.5f * (s.conic_a * dx * dx + s.conic_c * dy * dy) -
            s.conic_b * dx * dy;
        const float G = FastExp(power);
        const float raw = s.opacity * G;
        const float alpha = std::min(kMaxAlpha, raw);
        const bool valid =
            j < st->last[r][c] && power <= 0.f && alpha >= kMinAlpha;
        const float one_minus = 1.f - alpha;
        const float T = valid ? st->T[r][c] / one_minus : st->T[r][c];
        const float w = valid ? alpha * T : 0.f;
        const float la = st->last_alpha[r][c];
        float dL_dalpha = 0.f;
        const float col[3] = {s.color[0], s.color[1], s.color[2]};
        for (int ch = 0; ch < 3; ++ch) {
          const float acc =
              la * st->last_color[ch][r][c] + (1.f - la) * st->accum[ch][r][c];
          dL_dalpha += (col[ch] - acc) * st->dpix[ch][r][c];
          st->accum[ch][r][c] = valid ? acc : st->accum[ch][r][c];
          st->last_color[ch][r][c] = valid ? col[ch] : st->last_color[ch][r][c];
        }
        g_r += w * st->dpix[0][r][c];
        g_g += w * st->dpix[1][r][c];
        g_bl += w * st->dpix[2][r][c];
        dL_dalpha =
            dL_dalpha * T - st->T_final[r][c] / one_minus * st->bg_dot[r][c];
        st->T[r][c] = T;
        st->last_alpha[r][c] = valid ? alpha : la;
        const float dL_draw = valid && raw < kMaxAlpha ? dL_dalpha : 0.f;
        const float dL_dpower = dL_draw * raw;
        g_op += G * dL_draw;
        g_mx += dL_dpower * (s.conic_a * dx + s.conic_b * dy);
        g_my += dL_dpower * (s.conic_c * dy + s.conic_b * dx);
        g_a += dL_dpower * (-0.5f * dx * dx);
        g_b += dL_dpower * (-dx * dy);
        g_c += dL_dpower * (-0.5f * dy * dy);
      }
    }
    SplatGrad& o = out[list[j]];
    o.mean_x += g_mx, o.mean_y += g_my;
    o.conic_a += g_a, o.conic_b += g_b, o.conic_c += g_c;
    o.opacity += g_op;
    o.color[0] += g_r, o.color[1] += g_g, o.color[2] += g_bl;
  }
}

}  // namespace

void RasterizeBackward(const std::vector<Splat>& splats, const TileBins& bins,
                       const std::array<float, 3>& background,
                       const BlendState& state, const ImageRGB& grad_image,
                       std::vector<SplatGrad>* grads) {
  const size_t n = splats.size();
  const int threads = omp_get_max_threads();
  // Thread 0 writes straight into `grads`; the others into scratch buffers.
  grads->assign(n, SplatGrad());
  std::vector<std::vector<SplatGrad>> scratch(std::max(0, threads - 1));
  const int range_w = bins.range.x1 - bins.range.x0;
  const int num_tiles = bins.NumTiles();
#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num();
    SplatGrad* out = grads->data();
    if (tid > 0) {
      scratch[tid - 1].assign(n, SplatGrad());
      out = scratch[tid - 1].data();
    }
    TileState st;
    // Static round-robin: which thread sums which tile is fixed, so the
    // result does not depend on timing.
#pragma omp for schedule(static, 1)
    for (int k = 0; k < num_tiles; ++k) {
      const int tx = bins.range.x0 + k % range_w;
      const int ty = bins.range.y0 + k / range_w;
      BackwardTile(splats, bins.ids.data() + bins.offsets[k], tx, ty,
                   background, state, grad_image, &st, out);
    }
  }
  if (scratch.empty()) return;
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < n; ++i) {
    SplatGrad& g = (*grads)[i];
    for (const std::vector<SplatGrad>& buf : scratch) {
      const SplatGrad& b = buf[i];
      g.mean_x += b.mean_x, g.mean_y += b.mean_y;
      g.conic_a += b.conic_a, g.conic_b += b.conic_b, g.conic_c += b.conic_c;
      g.opacity += b.opacity;
      for (int ch = 0; ch < 3; ++ch) g.color[ch] += b.color[ch];
    }
  }
}

}  // namespace watergs
