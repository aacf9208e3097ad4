// A plain, obviously correct twin of the CPU rasterizer in double precision:
// for every pixel, every Gaussian in depth order, with Inria's rules written
// out directly (Eigen matrices, no tiles lists, no SIMD). Tests compare the
// fast rasterizer's images with it and take finite differences through it.
#pragma once

#include <cstdint>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// GaussianModel in double, so finite-difference steps are not rounded.
struct ReferenceModel {
  // Same meaning and layout as GaussianModel's fields.
  int sh_degree = 3;
  std::vector<double> means, log_scales, quats, opacity_logits, sh_dc, sh_rest;
  // Optional N x 2 pixel shifts added to the projected means (empty: none),
  // so tests can differentiate with respect to the screen-space mean.
  std::vector<double> screen_offsets;
  // Number of Gaussians.
  size_t size() const { return opacity_logits.size(); }
  // Floats of sh_rest per Gaussian.
  int sh_rest_stride() const { return 3 * (NumShCoeffs(sh_degree) - 1); }
  // Exact copy of a float model.
  static ReferenceModel From(const GaussianModel& model);
};

// The discrete choices of a render (per pixel, the ids of the contributing
// Gaussians in blending order). Replaying them holds tile membership, the
// 1/255 cut-off, the early stop and the depth order fixed, so finite
// differences see the smooth piece the analytic backward differentiates.
struct ReferenceDecisions {
  // Per rect pixel (row-major), contributing Gaussian ids front to back.
  std::vector<std::vector<uint32_t>> contributors;
};

// Renders options.rect (or the full frame) in double: rect.height x
// rect.width x 3 values. If `replay` is given its decisions are used instead
// of the tests; if `record` is given the decisions taken are stored there.
std::vector<double> ReferenceRender(const ReferenceModel& model,
                                    const RenderCamera& camera,
                                    const RenderOptions& options,
                                    const ReferenceDecisions* replay = nullptr,
                                    ReferenceDecisions* record = nullptr);

}  // namespace watergs
