// The differentiable rasterizer's public interface. Training, watermark
// embedding and extraction use the rasterizer only through this header; the
// CPU implementation (cpu_rasterizer.h) and a future CUDA one implement it.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/render_conventions.h"

namespace watergs {

// A pixel rectangle [x0, x0 + width) x [y0, y0 + height) of the full frame.
struct PixelRect {
  int x0 = 0, y0 = 0, width = 0, height = 0;
  bool empty() const { return width <= 0 || height <= 0; }
};

struct RenderOptions {
  // Colour composited behind the Gaussians.
  std::array<float, 3> background = {0.f, 0.f, 0.f};
  // SH degree used for colour (<= model.sh_degree); -1 means model.sh_degree.
  int active_sh_degree = -1;
  // Region of the frame to render; empty means the whole frame. The output
  // image then has the rectangle's size and the cost scales with its area.
  PixelRect rect;
  // Another renderer's per-splat conventions (render_conventions.h); the
  // default renders as Inria does. CPU only: Backward differentiates the
  // centre cull, the SH cap and the unclamped Jacobian and refuses the rest;
  // the CUDA rasterizer refuses any of them.
  RenderConventions conventions;
};

// Gradients of a scalar loss with respect to every model array, same shapes
// as GaussianModel, plus what density control needs.
struct GaussianGradients {
  // Left empty when compact_sh (see below).
  std::vector<float> means, log_scales, quats, opacity_logits, sh_dc, sh_rest;
  // Set by the caller before Backward: store the SH gradients in factored
  // form. One view's SH gradient of a Gaussian is rank 1 (the SH basis of
  // its view direction times dL/dcolour), so 6 floats replace 48 at degree 3
  // and ShCoefficientGradients expands them exactly when needed.
  bool compact_sh = false;
  // When compact_sh: per Gaussian dL/d(colour) with clamped channels zeroed
  // (3), and its unnormalised view direction mean - camera centre (3).
  std::vector<float> sh_color_grad, sh_view_dir;
  // When compact_sh: the SH degree the view was rendered with.
  int sh_active_degree = 0;
  // Per Gaussian: norm |(gx, gy)| of dL/d(mean2d), mean2d in pixels, for
  // this view (0 if not visible). A threshold t in Inria's units is about
  // t / (W/2) here for square-ish pixels; prefer mean2d_grad_norm_ndc.
  std::vector<float> mean2d_grad_norm;
  // Per Gaussian: Inria's densification statistic exactly, the same gradient
  // in NDC units |(gx W/2, gy H/2)|, W x H the full frame even for a crop:
  // compare this one with Inria's 2e-4 threshold (for the same loss scale,
  // i.e. a loss averaged over the rendered pixels as Inria's is).
  std::vector<float> mean2d_grad_norm_ndc;
  // Per Gaussian: 1 if it was visible in this view: Inria's radius > 0 with
  // its tile rectangle overlapping the rendered rectangle.
  std::vector<uint8_t> visible;
  // Zero-sized to n Gaussians with sh_rest stride `rest_stride`.
  void Reset(size_t n, int rest_stride);
};

// What a forward pass keeps for its backward pass (opaque to callers).
class RenderContext {
 public:
  virtual ~RenderContext() = default;
};

class Rasterizer {
 public:
  virtual ~Rasterizer() = default;
  // Renders `model` from `camera`; output has the rect's size (or the frame's).
  // `context` receives what Backward needs; may be null for render-only use.
  virtual void Forward(const GaussianModel& model, const RenderCamera& camera,
                       const RenderOptions& options, ImageRGB* image,
                       std::unique_ptr<RenderContext>* context) = 0;
  // dL/d(image) has the output image's shape; gradients are overwritten.
  // Exact gradients of the forward pass (the CPU one differs from Inria's
  // kernel only where alpha is capped at 0.99: zero slope there).
  virtual void Backward(const GaussianModel& model,
                        const RenderContext& context,
                        const ImageRGB& grad_image,
                        GaussianGradients* grads) = 0;
  // Adds to (*weights)[i], for every Gaussian i, the sum over the rendered
  // pixels of its blending weight alpha_i * T_i (its share of each pixel's
  // colour, what LightGaussian's global significance sums over the training
  // views). `weights` must hold model.size() entries. The base class throws
  // Error: only the CPU rasterizer computes it (pruning runs once, offline).
  virtual void AccumulateBlendWeights(const GaussianModel& model,
                                      const RenderCamera& camera,
                                      const RenderOptions& options,
                                      std::vector<double>* weights);
};

// The multithreaded CPU rasterizer (OpenMP over tiles).
std::unique_ptr<Rasterizer> MakeCpuRasterizer();

// `inner` rendering every view under `conventions` whatever the caller's
// options say: code that reads renders (extraction) sees what another
// renderer shows. Backward goes to `inner`, which refuses what it cannot
// differentiate.
std::unique_ptr<Rasterizer> WithConventions(
    std::unique_ptr<Rasterizer> inner, const RenderConventions& conventions);

}  // namespace watergs
