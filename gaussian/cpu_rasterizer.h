// The multithreaded CPU rasterizer: projection + SH colour per Gaussian,
// depth sort, tile binning, blending, and the matching backward, wired
// behind the Rasterizer interface (rasterizer.h).
#pragma once

#include <memory>
#include <vector>

#include "gaussian/projection.h"
#include "gaussian/rasterize_backward.h"
#include "gaussian/rasterize_forward.h"
#include "gaussian/rasterizer.h"
#include "gaussian/tile_binning.h"

namespace watergs {

// What a CPU forward pass keeps for its backward pass.
class CpuRenderContext : public RenderContext {
 public:
  // Camera in the projection's form.
  ProjectionCamera camera;
  // Frame size the pixel-space gradients refer to.
  int frame_width = 0, frame_height = 0;
  // SH degree the colours used.
  int active_sh_degree = 0;
  // The conventions the forward pass rendered with.
  RenderConventions conventions;
  // Background the forward pass composited.
  std::array<float, 3> background = {0, 0, 0};
  // Number of Gaussians in the model rendered.
  size_t num_gaussians = 0;
  // Gaussian id of each splat (splats are depth-sorted).
  std::vector<uint32_t> splat_ids;
  // Bit c set: colour channel c was clamped at 0 (no gradient).
  std::vector<uint8_t> color_clamped;
  // The blended splats, their tile lists and per-pixel blend state.
  std::vector<Splat> splats;
  TileBins bins;
  BlendState blend;
  // Per model Gaussian: 1 if it was binned into a rendered tile.
  std::vector<uint8_t> visible;
  // Bytes held by this context (for the benchmark's memory figure).
  size_t Bytes() const;
};

class CpuRasterizer : public Rasterizer {
 public:
  void Forward(const GaussianModel& model, const RenderCamera& camera,
               const RenderOptions& options, ImageRGB* image,
               std::unique_ptr<RenderContext>* context) override;
  void Backward(const GaussianModel& model, const RenderContext& context,
                const ImageRGB& grad_image, GaussianGradients* grads) override;
  void AccumulateBlendWeights(const GaussianModel& model,
                              const RenderCamera& camera,
                              const RenderOptions& options,
                              std::vector<double>* weights) override;
};

// Checks the options against the camera and model; returns the pixel rect
// to render (the full frame when options.rect is empty). Throws Error.
PixelRect ResolveRenderRect(const RenderCamera& camera,
                            const RenderOptions& options);

}  // namespace watergs
