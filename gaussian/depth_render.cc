// Expected depth through the rasterizer's colour path (see depth_render.h).
#include "gaussian/depth_render.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace watergs {

std::vector<float> RenderDepth(Rasterizer& rasterizer,
                               const GaussianModel& model,
                               const RenderCamera& camera,
                               double min_coverage) {
  // Red: depth / scale, in [0, 1] so that no colour clamp touches it (SH
  // colours are clamped at 0); green: 1, which blends to the coverage; blue 0.
  // The scale is the largest depth in front of the camera.
  const size_t n = model.size();
  std::vector<float> depth(n);
  float scale = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x(model.means[3 * i], model.means[3 * i + 1],
                            model.means[3 * i + 2]);
    depth[i] = float((camera.R * x + camera.t).z());
    if (std::isfinite(depth[i])) scale = std::max(scale, depth[i]);
  }
  std::vector<float> out(size_t(camera.width) * camera.height,
                         std::numeric_limits<float>::quiet_NaN());
  if (scale <= 0) return out;  // nothing in front of the camera
  GaussianModel coloured;
  coloured.sh_degree = 0;
  coloured.means = model.means;
  coloured.log_scales = model.log_scales;
  coloured.quats = model.quats;
  coloured.opacity_logits = model.opacity_logits;
  coloured.sh_dc.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    const float red =
        std::isfinite(depth[i]) && depth[i] > 0 ? depth[i] / scale : 0.f;
    coloured.sh_dc[3 * i] = RgbToShDc(red);
    coloured.sh_dc[3 * i + 1] = RgbToShDc(1.f);
    coloured.sh_dc[3 * i + 2] = RgbToShDc(0.f);
  }
  RenderOptions options;  // black background: it adds nothing to either sum
  ImageRGB image;
  rasterizer.Forward(coloured, camera, options, &image, nullptr);
  for (size_t p = 0; p < out.size(); ++p) {
    const float coverage = image.data[3 * p + 1];
    if (coverage >= min_coverage) {
      out[p] = image.data[3 * p] / coverage * scale;
    }
  }
  return out;
}

}  // namespace watergs
