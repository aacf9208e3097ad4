// The fast CPU forward pass against the double-precision reference twin, and
// crop renders against the matching part of a full render.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/reference_rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

// Largest |fast - reference| over all values.
double MaxDifference(const ImageRGB& fast, const std::vector<double>& ref) {
  EXPECT_EQ(fast.data.size(), ref.size());
  double worst = 0;
  for (size_t k = 0; k < ref.size(); ++k) {
    worst = std::max(worst, std::abs(double(fast.data[k]) - ref[k]));
  }
  return worst;
}

TEST(RasterizerForward, MatchesReferenceOnRandomScenes) {
  auto rasterizer = MakeCpuRasterizer();
  for (unsigned seed = 0; seed < 6; ++seed) {
    const RenderCamera cam = RandomCamera(70 + seed * 7, 45 + seed * 5, seed);
    SceneSpec spec;
    spec.count = 60;
    spec.sh_degree = seed % 4;
    spec.max_logit = seed % 2 ? 6.0 : 2.0;  // Opaque scenes stop early.
    const GaussianModel model = RandomScene(cam, spec, 100 + seed);
    RenderOptions options;
    options.background = {0.1f * seed, 0.5f, 1.0f - 0.1f * seed};
    ImageRGB image;
    rasterizer->Forward(model, cam, options, &image, nullptr);
    const std::vector<double> ref =
        ReferenceRender(ReferenceModel::From(model), cam, options);
    ASSERT_EQ(image.width, cam.width);
    ASSERT_EQ(image.height, cam.height);
    // Float blending vs double: measured ~5e-7, i.e. a few float ulps per
    // layer.
    EXPECT_LT(MaxDifference(image, ref), 1e-5) << "seed " << seed;
  }
}

TEST(RasterizerForward, ImageIsNotTrivial) {
  // Guards the comparison above against both sides rendering background.
  const RenderCamera cam = RandomCamera(64, 48, 3);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 7);
  ImageRGB image;
  MakeCpuRasterizer()->Forward(model, cam, RenderOptions(), &image, nullptr);
  int lit = 0;
  for (float v : image.data) lit += v > 0.05f;
  EXPECT_GT(lit, static_cast<int>(image.data.size() / 4));
}

TEST(RasterizerForward, LowerActiveShDegreeIgnoresHigherBands) {
  const RenderCamera cam = RandomCamera(48, 40, 5);
  SceneSpec spec;
  spec.sh_degree = 3;
  GaussianModel model = RandomScene(cam, spec, 9);
  RenderOptions options;
  options.active_sh_degree = 1;
  ImageRGB a, b;
  MakeCpuRasterizer()->Forward(model, cam, options, &a, nullptr);
  // Bands 2 and 3 live at sh_rest coefficients 3.. (each rgb).
  for (size_t i = 0; i < model.size(); ++i) {
    for (int k = 9; k < model.sh_rest_stride(); ++k) {
      model.sh_rest[i * model.sh_rest_stride() + k] = 5.0f;
    }
  }
  MakeCpuRasterizer()->Forward(model, cam, options, &b, nullptr);
  EXPECT_EQ(a.data, b.data);
  const std::vector<double> ref =
      ReferenceRender(ReferenceModel::From(model), cam, options);
  EXPECT_LT(MaxDifference(b, ref), 1e-5);
}

TEST(RasterizerForward, CropEqualsPartOfFullRender) {
  auto rasterizer = MakeCpuRasterizer();
  const RenderCamera cam = RandomCamera(100, 75, 11);
  SceneSpec spec;
  spec.count = 150;
  const GaussianModel model = RandomScene(cam, spec, 12);
  ImageRGB full;
  rasterizer->Forward(model, cam, RenderOptions(), &full, nullptr);
  // Rects aligned and unaligned with tiles, at borders, and single pixels.
  const PixelRect rects[] = {{0, 0, 100, 75}, {16, 16, 32, 32},
                             {5, 9, 37, 23},  {83, 60, 17, 15},
                             {99, 74, 1, 1},  {0, 40, 100, 3}};
  for (const PixelRect& rect : rects) {
    RenderOptions options;
    options.rect = rect;
    ImageRGB crop;
    rasterizer->Forward(model, cam, options, &crop, nullptr);
    ASSERT_EQ(crop.width, rect.width);
    ASSERT_EQ(crop.height, rect.height);
    for (int y = 0; y < rect.height; ++y) {
      for (int x = 0; x < rect.width; ++x) {
        for (int ch = 0; ch < 3; ++ch) {
          ASSERT_EQ(crop.At(x, y)[ch], full.At(rect.x0 + x, rect.y0 + y)[ch])
              << "rect " << rect.x0 << "," << rect.y0 << " pixel " << x << ","
              << y;
        }
      }
    }
    const std::vector<double> ref =
        ReferenceRender(ReferenceModel::From(model), cam, options);
    EXPECT_LT(MaxDifference(crop, ref), 1e-5);
  }
}

TEST(RasterizerForward, CropBinsOnlyTilesInsideTheRect) {
  const RenderCamera cam = RandomCamera(160, 160, 13);
  SceneSpec spec;
  spec.count = 300;
  const GaussianModel model = RandomScene(cam, spec, 14);
  RenderOptions options;
  options.rect = {32, 48, 20, 20};
  ImageRGB crop;
  std::unique_ptr<RenderContext> context;
  MakeCpuRasterizer()->Forward(model, cam, options, &crop, &context);
  const auto& ctx = dynamic_cast<const CpuRenderContext&>(*context);
  // Pixels 32..51 x 48..67 lie in tiles 2..3 x 3..4.
  EXPECT_EQ(ctx.bins.range.x0, 2);
  EXPECT_EQ(ctx.bins.range.x1, 4);
  EXPECT_EQ(ctx.bins.range.y0, 3);
  EXPECT_EQ(ctx.bins.range.y1, 5);
  EXPECT_EQ(ctx.bins.NumTiles(), 4);
  EXPECT_EQ(ctx.blend.final_T.size(), 400u);
  EXPECT_LT(ctx.splats.size(), model.size());
}

TEST(RasterizerForward, RejectsRectOutsideFrame) {
  const RenderCamera cam = RandomCamera(32, 32, 1);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 1);
  RenderOptions options;
  options.rect = {20, 20, 20, 5};
  ImageRGB image;
  EXPECT_THROW(
      MakeCpuRasterizer()->Forward(model, cam, options, &image, nullptr),
      Error);
}

}  // namespace
}  // namespace watergs
