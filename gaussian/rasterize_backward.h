// Backward of the tile blending (Inria's back-to-front walk per pixel):
// dL/d(image) to per-splat gradients of the 2D mean, conic, opacity and
// colour. Each (tile, splat) entry gets its own gradient slot and the slots
// are summed per splat in tile order afterwards, so results are
// deterministic whatever the thread count and schedule.
#pragma once

#include <array>
#include <vector>

#include "gaussian/image.h"
#include "gaussian/rasterize_forward.h"

namespace watergs {

// Gradients of one splat's blending inputs.
struct SplatGrad {
  // dL/d(pixel-space mean).
  float mean_x = 0, mean_y = 0;
  // dL/d(conic a, b, c).
  float conic_a = 0, conic_b = 0, conic_c = 0;
  // dL/d(opacity after the sigmoid).
  float opacity = 0;
  // dL/d(clamped colour).
  float color[3] = {0, 0, 0};
};

// grad_image: rect-sized dL/d(image). Fills one SplatGrad per splat. The
// alpha cap at 0.99 is differentiated exactly (zero slope where it binds),
// unlike Inria's kernel which ignores it.
void RasterizeBackward(const std::vector<Splat>& splats, const TileBins& bins,
                       const std::array<float, 3>& background,
                       const BlendState& state, const ImageRGB& grad_image,
                       std::vector<SplatGrad>* grads);

}  // namespace watergs
