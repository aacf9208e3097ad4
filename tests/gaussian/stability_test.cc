// Numerical stability of the training pieces outside the rasterizer: SSIM
// on constant images (value and gradient finite, gradient still correct),
// Adam under zero, huge and non-finite gradients (nothing non-finite reaches
// a parameter or a moment), and a training run whose density control prunes
// every Gaussian (a clear error, no crash).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "gaussian/adam.h"
#include "gaussian/loss.h"
#include "gaussian/trainer.h"
#include "gaussian/util/error.h"
#include "tests/common/look_at.h"

namespace watergs {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// x, y: w x h single-channel constant images of values a and b.
struct ConstantPair {
  std::vector<double> x, y;
};
ConstantPair Constants(int w, int h, double a, double b) {
  return {std::vector<double>(w * h, a), std::vector<double>(w * h, b)};
}

TEST(Stability, SsimOfConstantImagesHasFiniteValueAndCorrectGradient) {
  const int w = 7, h = 6;
  // Equal, black, white, black vs white, and nearly equal constants (the
  // variances are all zero: only C1 and C2 keep the ratio defined).
  const double pairs[][2] = {{0, 0}, {1, 1}, {0.5, 0.5},
                             {0, 1}, {1, 0}, {0.3, 0.3 + 1e-9}};
  for (const auto& pair : pairs) {
    ConstantPair images = Constants(w, h, pair[0], pair[1]);
    std::vector<double> grad(w * h);
    const double value =
        SsimInterleaved(images.x.data(), images.y.data(), w, h, 1, grad.data());
    ASSERT_TRUE(std::isfinite(value)) << pair[0] << " " << pair[1];
    EXPECT_LE(value, 1.0 + 1e-12);
    if (pair[0] == pair[1]) {
      EXPECT_NEAR(value, 1.0, 1e-12);
    }
    // The gradient is finite and matches central differences in double.
    for (int i = 0; i < w * h; ++i) {
      ASSERT_TRUE(std::isfinite(grad[i]));
      const double step = 1e-6;
      std::vector<double> plus = images.x, minus = images.x;
      plus[i] += step;
      minus[i] -= step;
      const double numeric =
          (SsimInterleaved<double>(plus.data(), images.y.data(), w, h, 1,
                                   nullptr) -
           SsimInterleaved<double>(minus.data(), images.y.data(), w, h, 1,
                                   nullptr)) /
          (2 * step);
      EXPECT_NEAR(grad[i], numeric, 1e-6 + 1e-4 * std::abs(numeric))
          << "pixel " << i << " of " << pair[0] << " vs " << pair[1];
    }
  }
}

TEST(Stability, SsimOfFloatConstantImagesIsFinite) {
  for (float a : {0.f, 1.f}) {
    ImageRGB x(16, 16), y(16, 16);
    std::fill(x.data.begin(), x.data.end(), a);
    std::fill(y.data.begin(), y.data.end(), 1.f - a);
    ImageRGB grad;
    EXPECT_TRUE(std::isfinite(Ssim(x, y, &grad)));
    for (float g : grad.data) ASSERT_TRUE(std::isfinite(g));
    EXPECT_NEAR(Ssim(x, x, &grad), 1.0, 1e-6);
    for (float g : grad.data) ASSERT_TRUE(std::isfinite(g));
  }
}

GaussianModel SmallModel(size_t n) {
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(n);
  std::mt19937 rng(3);
  std::normal_distribution<float> normal;
  for (ParamGroup g :
       {ParamGroup::kXyz, ParamGroup::kFDc, ParamGroup::kFRest,
        ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation}) {
    for (float& v : GroupParams(model, g)) v = normal(rng);
  }
  return model;
}

// Every gradient value set to `value`.
GaussianGradients Filled(const GaussianModel& model, float value) {
  GaussianGradients grads;
  grads.Reset(model.size(), model.sh_rest_stride());
  for (auto* v : {&grads.means, &grads.sh_dc, &grads.sh_rest,
                  &grads.opacity_logits, &grads.log_scales, &grads.quats}) {
    std::fill(v->begin(), v->end(), value);
  }
  return grads;
}

bool MomentsFinite(Adam& adam) {
  for (int g = 0; g < kNumParamGroups; ++g) {
    const AdamGroupState& s = adam.state(static_cast<ParamGroup>(g));
    for (const auto* v : {&s.exp_avg, &s.exp_avg_sq, &s.exp_avg_sq_shared}) {
      for (float x : *v) {
        if (!std::isfinite(x)) return false;
      }
    }
  }
  return true;
}

class AdamStability : public ::testing::TestWithParam<bool> {};

TEST_P(AdamStability, ZeroHugeAndNonFiniteGradientsKeepEverythingFinite) {
  AdamOptions options;
  options.compact_moments = GetParam();
  Adam adam(options, 1.0);
  GaussianModel model = SmallModel(5);
  adam.Init(model);
  // Zero gradients from a fresh state move nothing (0 / (0 + eps) = 0).
  const GaussianModel start = model;
  for (int it = 1; it <= 3; ++it) {
    adam.SetIteration(it);
    adam.Step(Filled(model, 0.f), &model);
  }
  EXPECT_EQ(model.means, start.means);
  EXPECT_EQ(model.opacity_logits, start.opacity_logits);
  // Huge finite gradients: Adam's step is bounded by about the learning rate
  // whatever the gradient's size (|m / sqrt(v)| <= ~1 after correction).
  int it = 4;
  for (float huge : {1e30f, -1e30f, 3e38f, -3e38f}) {
    const GaussianModel before = model;
    adam.SetIteration(it++);
    adam.Step(Filled(model, huge), &model);
    ASSERT_EQ(model.CountNonFinite(), 0u) << huge;
    ASSERT_TRUE(MomentsFinite(adam)) << huge;
    for (size_t i = 0; i < model.opacity_logits.size(); ++i) {
      EXPECT_LE(std::abs(model.opacity_logits[i] - before.opacity_logits[i]),
                20 * options.opacity_lr)
          << huge;
    }
  }
  // Non-finite gradients are rejected value by value.
  for (float bad : {kInf, -kInf, kNaN}) {
    adam.SetIteration(it++);
    const size_t rejected = adam.Step(Filled(model, bad), &model);
    EXPECT_GT(rejected, 0u);
    ASSERT_EQ(model.CountNonFinite(), 0u) << bad;
    ASSERT_TRUE(MomentsFinite(adam)) << bad;
  }
  // After all that, ordinary gradients still move the parameters.
  const GaussianModel before = model;
  adam.SetIteration(it++);
  adam.Step(Filled(model, 1e-3f), &model);
  EXPECT_EQ(model.CountNonFinite(), 0u);
  EXPECT_NE(model.opacity_logits, before.opacity_logits);
}

INSTANTIATE_TEST_SUITE_P(FullAndCompactMoments, AdamStability,
                         ::testing::Values(false, true));

// Views of a small random ball of Gaussians.
struct Scene {
  InMemoryViews views;
  std::vector<size_t> train;
};
Scene MakeScene() {
  Scene s;
  GaussianModel truth = SmallModel(30);
  for (float& v : truth.means) v *= 0.3f;
  for (float& v : truth.log_scales) v = std::log(0.1f);
  auto rasterizer = MakeCpuRasterizer();
  for (int v = 0; v < 3; ++v) {
    const double a = 2 * M_PI * v / 3;
    const RenderCamera camera = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 24, 20);
    ImageRGB image;
    rasterizer->Forward(truth, camera, RenderOptions{}, &image, nullptr);
    s.views.Add("view" + std::to_string(v), camera, image);
    s.train.push_back(v);
  }
  return s;
}

TEST(Stability, TrainingThatPrunesEveryGaussianStopsWithAClearError) {
  Scene s = MakeScene();
  // Every opacity below density control's min_opacity (0.005): the first
  // densification prunes them all.
  GaussianModel init = SmallModel(20);
  for (float& v : init.means) v *= 0.3f;
  for (float& v : init.opacity_logits) v = -12.f;
  TrainerOptions options;
  options.iterations = 20;
  options.adam.position_lr_max_steps = 20;
  options.density.densify_from_iter = 2;
  options.density.densification_interval = 3;
  Trainer trainer(options, s.views, s.train, init, 2.0, MakeCpuRasterizer());
  try {
    trainer.Run();
    ADD_FAILURE() << "training went on with " << trainer.model().size()
                  << " Gaussians";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("pruned every Gaussian"), std::string::npos)
        << message;
    EXPECT_NE(message.find("iteration 3"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace watergs
