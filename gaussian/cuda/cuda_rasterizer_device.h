// The CUDA rasterizer as a class, with device-resident entry points next to
// the Rasterizer interface's host ones: a GPU trainer keeps the model, the
// image and the gradients on the device and skips the per-iteration copies
// of ~0.5 KB per Gaussian that the host interface needs. Both paths run the
// same kernels (raster_kernels.h) and give the same results.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "gaussian/rasterizer.h"

namespace watergs {

// A model's arrays on the device, GaussianModel layout.
struct CudaModelArrays {
  // N x 3, N x 3, N x 4, N, N x 3, N x 3 (NumShCoeffs(sh_degree) - 1).
  const float *means = nullptr, *log_scales = nullptr, *quats = nullptr,
              *opacity_logits = nullptr, *sh_dc = nullptr, *sh_rest = nullptr;
  // Highest SH degree stored (0-3).
  int sh_degree = 3;
  // Number of Gaussians N.
  size_t count = 0;
};

// Gradient arrays on the device, GaussianGradients layout; every array the
// mode uses is overwritten.
struct CudaGradientArrays {
  // N x 3, N x 3, N x 4, N.
  float *means = nullptr, *log_scales = nullptr, *quats = nullptr,
        *opacity_logits = nullptr;
  // Factored SH gradients (GaussianGradients::compact_sh).
  bool compact_sh = false;
  // Dense SH gradients (N x 3, N x rest stride) when not compact_sh.
  float *sh_dc = nullptr, *sh_rest = nullptr;
  // dL/dcolour and the view direction (N x 3 each) when compact_sh.
  float *sh_color_grad = nullptr, *sh_view_dir = nullptr;
  // N each: |dL/dmean2d| in pixels and in NDC units.
  float *mean2d_grad_norm = nullptr, *mean2d_grad_norm_ndc = nullptr;
  // N: 1 if visible in the view (may be null).
  uint8_t* visible = nullptr;
};

// Device memory of one pass (defined in cuda_rasterizer.cc).
struct CudaWorkspace;

class CudaRasterizer : public Rasterizer {
 public:
  // Throws Error if no CUDA device is usable.
  CudaRasterizer();
  ~CudaRasterizer() override;

  // The Rasterizer contract on host arrays (uploads the model, downloads
  // the image and the gradients).
  void Forward(const GaussianModel& model, const RenderCamera& camera,
               const RenderOptions& options, ImageRGB* image,
               std::unique_ptr<RenderContext>* context) override;
  void Backward(const GaussianModel& model, const RenderContext& context,
                const ImageRGB& grad_image, GaussianGradients* grads) override;

  // Forward on device arrays; `image` (device) receives the rect's
  // height x width x 3 floats. The model arrays are not copied: they must
  // stay unchanged until BackwardDevice on this context has run.
  void ForwardDevice(const CudaModelArrays& model, const RenderCamera& camera,
                     const RenderOptions& options, float* image,
                     std::unique_ptr<RenderContext>* context);
  // Backward of a ForwardDevice or Forward context: grad_image (device,
  // rect-sized HWC) to the gradient arrays `grads` (device).
  void BackwardDevice(const RenderContext& context, const float* grad_image,
                      const CudaGradientArrays& grads);
  // The N screen radii of a Forward or ForwardDevice context, as
  // ComputeScreenRadii gives them for its visible Gaussians (Inria's 3-sigma
  // radius in pixels where visible, else 0): computed by the projection, so
  // density control needs no second pass over the model.
  void DownloadScreenRadii(const RenderContext& context,
                           std::vector<float>* radii) const;
  // The same N radii on the device, in the context's workspace: valid while
  // `context` is alive.
  const float* DeviceScreenRadii(const RenderContext& context) const;

 private:
  // A pooled workspace no live context holds, or a new one.
  std::shared_ptr<CudaWorkspace> AcquireWorkspace();

  // Workspaces kept for reuse: two cover a caller that keeps the previous
  // context alive while rendering the next view.
  std::vector<std::shared_ptr<CudaWorkspace>> pool_;
};

}  // namespace watergs
