// Test helpers of the image-file tests (image_reading_cli_test.cc,
// detect_cli_test.cc): a model's renders at a workspace's cameras, as
// extract renders them, and what an 8-bit file of a render holds.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/rasterizer.h"
#include "plugin/workspace.h"

namespace watergs::testing {

// `model` rendered from every view of `workspace` (black background),
// clamped to [0, 1] as ExtractWatermark clamps its renders.
inline std::vector<ImageRGB> RenderViews(const GaussianModel& model,
                                         const Workspace& workspace) {
  auto rasterizer = MakeCpuRasterizer();
  std::vector<ImageRGB> renders(workspace.NumViews());
  for (size_t v = 0; v < workspace.NumViews(); ++v) {
    rasterizer->Forward(model, workspace.ViewCamera(v), RenderOptions{},
                        &renders[v], nullptr);
    for (float& value : renders[v].data) value = std::clamp(value, 0.f, 1.f);
  }
  return renders;
}

// The image as an 8-bit file holds it and a reader should give it back:
// each value rounded to the nearest of k / 255 (WriteImageFile's rounding).
inline ImageRGB Quantise8(const ImageRGB& image) {
  ImageRGB q = image;
  for (float& value : q.data) {
    value = float(std::lround(std::clamp(value, 0.f, 1.f) * 255.f)) / 255.f;
  }
  return q;
}

}  // namespace watergs::testing
