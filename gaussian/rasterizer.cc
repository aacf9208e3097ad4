#include "gaussian/rasterizer.h"

#include <utility>

#include "gaussian/util/error.h"

namespace watergs {

void GaussianGradients::Reset(size_t n, int rest_stride) {
  auto zero = [](std::vector<float>& v, size_t size) { v.assign(size, 0.f); };
  zero(means, n * 3);
  zero(log_scales, n * 3);
  zero(quats, n * 4);
  zero(opacity_logits, n);
  if (compact_sh) {
    sh_dc.clear(), sh_rest.clear();
    zero(sh_color_grad, n * 3);
    zero(sh_view_dir, n * 3);
  } else {
    zero(sh_dc, n * 3);
    zero(sh_rest, n * static_cast<size_t>(rest_stride));
  }
  zero(mean2d_grad_norm, n);
  zero(mean2d_grad_norm_ndc, n);
  visible.assign(n, 0);
}

void Rasterizer::AccumulateBlendWeights(const GaussianModel&,
                                        const RenderCamera&,
                                        const RenderOptions&,
                                        std::vector<double>*) {
  Fail(
      "render: per-Gaussian blend weights are computed by the CPU rasterizer "
      "only");
}

namespace {

class ConventionsRasterizer : public Rasterizer {
 public:
  ConventionsRasterizer(std::unique_ptr<Rasterizer> inner,
                        const RenderConventions& conventions)
      : inner_(std::move(inner)), conventions_(conventions) {}
  void Forward(const GaussianModel& model, const RenderCamera& camera,
               const RenderOptions& options, ImageRGB* image,
               std::unique_ptr<RenderContext>* context) override {
    inner_->Forward(model, camera, WithOurs(options), image, context);
  }
  void Backward(const GaussianModel& model, const RenderContext& context,
                const ImageRGB& grad_image, GaussianGradients* grads) override {
    inner_->Backward(model, context, grad_image, grads);
  }
  void AccumulateBlendWeights(const GaussianModel& model,
                              const RenderCamera& camera,
                              const RenderOptions& options,
                              std::vector<double>* weights) override {
    inner_->AccumulateBlendWeights(model, camera, WithOurs(options), weights);
  }

 private:
  RenderOptions WithOurs(RenderOptions options) const {
    options.conventions = conventions_;
    return options;
  }
  std::unique_ptr<Rasterizer> inner_;
  RenderConventions conventions_;
};

}  // namespace

std::unique_ptr<Rasterizer> WithConventions(
    std::unique_ptr<Rasterizer> inner, const RenderConventions& conventions) {
  CheckRenderConventions(conventions);
  return std::make_unique<ConventionsRasterizer>(std::move(inner), conventions);
}

}  // namespace watergs
