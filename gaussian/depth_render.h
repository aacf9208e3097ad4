// Per-pixel depth of a model through any Rasterizer's public interface: the
// model recoloured so that one channel carries each Gaussian's camera depth
// and another a constant 1, blended as colour is. Their ratio is the
// blending-weighted mean depth of the pixel (the "expected depth" gsplat
// renders as ED), with no depth pass in the rasterizer itself. Used to lift
// features of a render to 3D (plugin/image_registration.h).
#pragma once

#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// H x W depths along the camera's z axis (world units), row-major; NaN where
// the Gaussians cover less than `min_coverage` of the pixel (their summed
// blending weight), the background showing through.
std::vector<float> RenderDepth(Rasterizer& rasterizer,
                               const GaussianModel& model,
                               const RenderCamera& camera,
                               double min_coverage = 0.5);

}  // namespace watergs
