// The CPU rasterizer's per-Gaussian accumulated blend weight (sum over pixels
// of alpha * T) against a brute-force computation: the double-precision
// reference renders the scene once per Gaussian with that Gaussian white and
// every other one black over a black background, so each pixel's value is
// exactly that Gaussian's weight there (colour does not change alpha).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/reference_rasterizer.h"
#include "gaussian/sh.h"
#include "gaussian/util/error.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

// Sum over the frame of Gaussian `which`'s blending weight, from renders of
// the reference twin.
double BruteForceWeight(const GaussianModel& model, size_t which,
                        const RenderCamera& camera) {
  ReferenceModel ref = ReferenceModel::From(model);
  ref.sh_degree = 0;
  ref.sh_rest.clear();
  for (size_t i = 0; i < ref.size(); ++i) {
    // Colour 0.5 + C0 dc: 1 for `which`, exactly 0 (clamped) for the others.
    const double dc = i == which ? 0.5 / kShC0 : -1.0 / kShC0;
    for (int ch = 0; ch < 3; ++ch) ref.sh_dc[3 * i + ch] = dc;
  }
  const std::vector<double> image =
      ReferenceRender(ref, camera, RenderOptions());
  double sum = 0;
  for (size_t k = 0; k < image.size(); k += 3) sum += image[k];
  return sum;
}

TEST(BlendWeights, MatchBruteForceOnTinyScenes) {
  auto rasterizer = MakeCpuRasterizer();
  for (unsigned seed = 0; seed < 4; ++seed) {
    const RenderCamera cam = RandomCamera(40 + 5 * seed, 30 + 3 * seed, seed);
    SceneSpec spec;
    spec.count = 12;
    spec.sh_degree = 1;
    spec.max_logit = seed % 2 ? 6.0 : 2.0;  // Opaque scenes stop early.
    const GaussianModel model = RandomScene(cam, spec, 50 + seed);
    std::vector<double> weights(model.size(), 0.0);
    rasterizer->AccumulateBlendWeights(model, cam, RenderOptions(), &weights);
    double total = 0;
    for (size_t i = 0; i < model.size(); ++i) {
      const double expected = BruteForceWeight(model, i, cam);
      total += expected;
      // Float blending against double: a few ulps per layer and pixel.
      EXPECT_NEAR(weights[i], expected, 1e-4 * (1 + expected))
          << "seed " << seed << " Gaussian " << i;
    }
    // Guards against both sides being zero: the scene covers pixels.
    EXPECT_GT(total, 10.0) << "seed " << seed;
  }
}

TEST(BlendWeights, AccumulateOverCallsAndSkipInvisibleGaussians) {
  auto rasterizer = MakeCpuRasterizer();
  const RenderCamera cam = RandomCamera(48, 36, 9);
  SceneSpec spec;
  spec.count = 20;
  GaussianModel model = RandomScene(cam, spec, 3);
  // Gaussian 0 behind the camera, Gaussian 1 with zero opacity.
  for (int k = 0; k < 3; ++k) {
    model.means[k] = float(-10 * cam.R(2, k) - cam.R.col(k).dot(cam.t));
  }
  model.opacity_logits[1] = -INFINITY;
  std::vector<double> once(model.size(), 0.0), twice(model.size(), 0.0);
  rasterizer->AccumulateBlendWeights(model, cam, RenderOptions(), &once);
  rasterizer->AccumulateBlendWeights(model, cam, RenderOptions(), &twice);
  rasterizer->AccumulateBlendWeights(model, cam, RenderOptions(), &twice);
  EXPECT_EQ(once[0], 0.0);
  EXPECT_EQ(once[1], 0.0);
  for (size_t i = 0; i < model.size(); ++i) {
    EXPECT_TRUE(std::isfinite(once[i]));
    EXPECT_NEAR(twice[i], 2 * once[i], 1e-9 * (1 + once[i]));
  }
  // Each pixel's weights sum to 1 - T <= 1.
  double total = 0;
  for (double w : once) total += w;
  EXPECT_LE(total, double(cam.width) * cam.height);
  EXPECT_GT(total, 0.0);
  std::vector<double> wrong_size(3, 0.0);
  EXPECT_THROW(rasterizer->AccumulateBlendWeights(model, cam, RenderOptions(),
                                                  &wrong_size),
               Error);
}

}  // namespace
}  // namespace watergs
