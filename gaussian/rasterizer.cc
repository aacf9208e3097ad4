#include "gaussian/rasterizer.h"

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

}  // namespace watergs
