// Tests for the schedule queries the GPU trainer relies on
// (DensityStrategy::MayChangeModel and ReadsGradients): they must be exact
// for Inria's ADC, since the GPU path copies the model to the host only on
// MayChangeModel iterations and downloads gradients only on ReadsGradients
// ones.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/density_strategy.h"

namespace watergs {
namespace {

// n Gaussians with random means, small scales and opacity 0.5.
GaussianModel RandomModel(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      model.means[3 * i + a] = u(rng);
      model.log_scales[3 * i + a] = std::log(0.02f + 0.01f * u(rng));
    }
    model.quats[4 * i] = 1;
  }
  return model;
}

// Gradients for `model`: every Gaussian visible, NDC norms above the
// threshold for about half of them.
GaussianGradients Statistics(const GaussianModel& model, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 4e-4f);
  GaussianGradients g;
  g.visible.assign(model.size(), 1);
  g.mean2d_grad_norm_ndc.resize(model.size());
  for (float& v : g.mean2d_grad_norm_ndc) v = u(rng);
  return g;
}

// Runs `options`' strategy for `iterations` iterations and checks, per
// iteration, that the model and moments changed exactly where
// MayChangeModel says they may, and that PostBackward reads no gradients
// where ReadsGradients says it does not (it gets empty ones there, which it
// would refuse).
void ExpectExactSchedule(const DensityOptions& options, int64_t iterations) {
  GaussianModel model = RandomModel(30, 3);
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  auto strategy = MakeInriaDensityStrategy(options, 1.0);
  strategy->Init(model);
  int changes = 0;
  for (int64_t it = 1; it <= iterations; ++it) {
    const GaussianModel before = model;
    const bool reads = strategy->ReadsGradients(it);
    const GaussianGradients grads =
        reads ? Statistics(model, static_cast<uint32_t>(it))
              : GaussianGradients{};
    const std::vector<float> radii(model.size(), 1.f);
    // A step's worth of opacity moments, so that a reset shows in them.
    std::fill(adam.state(ParamGroup::kOpacity).exp_avg.begin(),
              adam.state(ParamGroup::kOpacity).exp_avg.end(), 0.5f);
    const std::vector<float> filled = adam.state(ParamGroup::kOpacity).exp_avg;
    const DensityEvent event = strategy->PostBackward(
        it, grads, strategy->WantsRadii(it) ? &radii : nullptr, &model, &adam);
    const bool changed = model.means != before.means ||
                         model.opacity_logits != before.opacity_logits ||
                         model.log_scales != before.log_scales ||
                         adam.state(ParamGroup::kOpacity).exp_avg != filled;
    EXPECT_EQ(changed || event.densified || event.opacity_reset,
              strategy->MayChangeModel(it))
        << "iteration " << it;
    changes += changed;
    if (model.size() == 0) break;
  }
  EXPECT_GT(changes, 2);
}

TEST(DensitySchedule, MayChangeModelIsExactForInria) {
  DensityOptions options;
  options.densify_from_iter = 4;
  options.densification_interval = 6;
  options.densify_until_iter = 40;
  options.opacity_reset_interval = 18;
  options.grad_threshold = 2e-4;
  ExpectExactSchedule(options, 50);
}

TEST(DensitySchedule, MayChangeModelCoversTheWhiteBackgroundReset) {
  DensityOptions options;
  options.densify_from_iter = 5;
  options.densification_interval = 7;
  options.densify_until_iter = 30;
  options.opacity_reset_interval = 20;
  options.white_background = true;
  ExpectExactSchedule(options, 35);
  auto strategy = MakeInriaDensityStrategy(options, 1.0);
  EXPECT_TRUE(strategy->MayChangeModel(5));  // the white-background reset
  EXPECT_FALSE(strategy->MayChangeModel(6));
  EXPECT_FALSE(strategy->ReadsGradients(30));
  EXPECT_TRUE(strategy->ReadsGradients(29));
}

TEST(DensitySchedule, FixedStrategyNeverChangesTheModel) {
  auto strategy = MakeFixedDensityStrategy();
  for (int64_t it : {1, 100, 3000, 15000}) {
    EXPECT_FALSE(strategy->MayChangeModel(it));
    EXPECT_FALSE(strategy->ReadsGradients(it));
  }
}

}  // namespace
}  // namespace watergs
