// Tests for Inria's adaptive density control on hand-built models: clone,
// split and prune counts, split sampling statistics, opacity reset, the
// schedule, and the Adam moments following the Gaussians.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/density_strategy.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

float Logit(float p) { return std::log(p / (1 - p)); }

// n Gaussians at x = i, isotropic scale `scale`, opacity `opacity`.
GaussianModel MakeModel(size_t n, float scale, float opacity) {
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    model.means[3 * i] = float(i);
    for (int a = 0; a < 3; ++a) model.log_scales[3 * i + a] = std::log(scale);
    model.quats[4 * i] = 1;
    model.opacity_logits[i] = Logit(opacity);
    model.sh_dc[3 * i] = 0.1f * i;
  }
  return model;
}

// Gradients where Gaussian i has view-space norm norms[i] (visible if > 0)
// and every parameter gradient is 1 (so one Adam step fills the moments).
GaussianGradients Grads(const GaussianModel& model,
                        const std::vector<float>& norms) {
  GaussianGradients g;
  g.Reset(model.size(), model.sh_rest_stride());
  g.mean2d_grad_norm_ndc.assign(model.size(), 0.f);
  for (auto* v : {&g.means, &g.sh_dc, &g.sh_rest, &g.opacity_logits,
                  &g.log_scales, &g.quats}) {
    std::fill(v->begin(), v->end(), 1.f);
  }
  for (size_t i = 0; i < model.size(); ++i) {
    g.mean2d_grad_norm_ndc[i] = norms[i];
    g.visible[i] = norms[i] > 0;
  }
  return g;
}

struct Fixture {
  GaussianModel model;
  Adam adam{AdamOptions{}, 1.0};
  std::unique_ptr<DensityStrategy> strategy;
  Fixture(GaussianModel m, DensityOptions options = {}) : model(std::move(m)) {
    adam.Init(model);
    strategy = MakeInriaDensityStrategy(options, 1.0);
    strategy->Init(model);
  }
};

TEST(Density, ClonesSmallGaussiansWithLargeGradients) {
  Fixture f(MakeModel(4, 0.001f, 0.5f));
  const GaussianGradients g = Grads(f.model, {3e-4f, 1e-4f, 2.5e-4f, 0.f});
  f.adam.Step(g, &f.model);
  const GaussianModel before = f.model;
  const auto dc_m = f.adam.state(ParamGroup::kFDc).exp_avg;
  const DensityEvent e =
      f.strategy->PostBackward(600, g, nullptr, &f.model, &f.adam);
  ASSERT_TRUE(e.densified);
  EXPECT_EQ(e.cloned, 2u);
  EXPECT_EQ(e.split, 0u);
  EXPECT_EQ(e.pruned, 0u);
  EXPECT_EQ(e.parent, (std::vector<int64_t>{0, 1, 2, 3, 0, 2}));
  ASSERT_EQ(f.model.size(), 6u);
  ASSERT_EQ(f.adam.size(), 6u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(f.model.means[12 + k], before.means[k]);
    EXPECT_EQ(f.model.means[15 + k], before.means[6 + k]);
    EXPECT_EQ(f.model.sh_dc[15 + k], before.sh_dc[6 + k]);
  }
  const auto& m = f.adam.state(ParamGroup::kFDc).exp_avg;
  for (int j = 0; j < 12; ++j) EXPECT_EQ(m[j], dc_m[j]);
  for (int j = 12; j < 18; ++j) EXPECT_EQ(m[j], 0.f);
}

TEST(Density, AveragesGradientOverVisibleViewsOnly) {
  Fixture f(MakeModel(3, 0.001f, 0.5f));
  // Gaussian 0: 3e-4 and 0 in two visible views -> mean 1.5e-4, no clone.
  // Gaussian 1: 3e-4 once, invisible in the other view -> mean 3e-4, clone.
  GaussianGradients a = Grads(f.model, {3e-4f, 3e-4f, 0.f});
  GaussianGradients b = Grads(f.model, {0.f, 0.f, 0.f});
  b.visible[0] = 1;
  EXPECT_FALSE(
      f.strategy->PostBackward(599, a, nullptr, &f.model, &f.adam).densified);
  const DensityEvent e =
      f.strategy->PostBackward(600, b, nullptr, &f.model, &f.adam);
  EXPECT_EQ(e.cloned, 1u);
  EXPECT_EQ(e.parent.back(), 1);
}

TEST(Density, SplitsLargeGaussiansAndSamplesTheirShape) {
  const size_t n = 3000;
  GaussianModel model = MakeModel(n, 0.05f, 0.5f);
  // Anisotropic (0.4, 0.05, 0.1), rotated 90 degrees about z: world x gets
  // the 0.05 axis and world y the 0.4 axis.
  const float s = std::sqrt(0.5f);
  for (size_t i = 0; i < n; ++i) {
    model.means[3 * i] = 1.f;
    model.log_scales[3 * i] = std::log(0.4f);
    model.log_scales[3 * i + 1] = std::log(0.05f);
    model.log_scales[3 * i + 2] = std::log(0.1f);
    model.quats[4 * i] = s;
    model.quats[4 * i + 3] = s;
  }
  DensityOptions options;
  options.seed = 7;
  Fixture f(model, options);
  const GaussianGradients g = Grads(f.model, std::vector<float>(n, 1e-3f));
  const DensityEvent e =
      f.strategy->PostBackward(700, g, nullptr, &f.model, &f.adam);
  EXPECT_EQ(e.split, n);
  EXPECT_EQ(e.cloned, 0u);
  ASSERT_EQ(f.model.size(), 2 * n);
  ASSERT_EQ(f.adam.size(), 2 * n);
  double var[3] = {0, 0, 0}, cov_xy = 0;
  for (size_t j = 0; j < 2 * n; ++j) {
    const double d[3] = {f.model.means[3 * j] - 1.0, f.model.means[3 * j + 1],
                         f.model.means[3 * j + 2]};
    for (int a = 0; a < 3; ++a) var[a] += d[a] * d[a] / (2 * n);
    cov_xy += d[0] * d[1] / (2 * n);
    EXPECT_NEAR(std::exp(f.model.log_scales[3 * j]), 0.4 / 1.6, 1e-6);
    EXPECT_NEAR(std::exp(f.model.log_scales[3 * j + 1]), 0.05 / 1.6, 1e-7);
  }
  // 6000 samples: the standard error of a variance is about 2%.
  EXPECT_NEAR(var[0], 0.05 * 0.05, 0.1 * 0.05 * 0.05);
  EXPECT_NEAR(var[1], 0.4 * 0.4, 0.1 * 0.4 * 0.4);
  EXPECT_NEAR(var[2], 0.1 * 0.1, 0.1 * 0.1 * 0.1);
  EXPECT_NEAR(cov_xy, 0.0, 0.1 * 0.05 * 0.4);
  for (float m : f.adam.state(ParamGroup::kXyz).exp_avg) EXPECT_EQ(m, 0.f);
}

TEST(Density, PrunesTransparentAlwaysAndOversizedAfterFirstReset) {
  // 0: transparent; 1: world-large (0.2 > 0.1 extent); 2: screen-large;
  // 3: ordinary. Gradients below threshold so nothing densifies.
  auto make = [] {
    GaussianModel m = MakeModel(4, 0.001f, 0.5f);
    m.opacity_logits[0] = Logit(0.004f);
    for (int a = 0; a < 3; ++a) m.log_scales[3 + a] = std::log(0.2f);
    return m;
  };
  const std::vector<float> radii = {1.f, 1.f, 25.f, 19.f};
  {
    Fixture f(make());
    const GaussianGradients g = Grads(f.model, {1e-5f, 1e-5f, 1e-5f, 1e-5f});
    const DensityEvent e =
        f.strategy->PostBackward(600, g, &radii, &f.model, &f.adam);
    EXPECT_EQ(e.pruned, 1u);
    EXPECT_EQ(e.parent, (std::vector<int64_t>{1, 2, 3}));
  }
  {
    Fixture f(make());
    EXPECT_TRUE(f.strategy->WantsRadii(3100));
    EXPECT_FALSE(f.strategy->WantsRadii(3000));
    const GaussianGradients g = Grads(f.model, {1e-5f, 1e-5f, 1e-5f, 1e-5f});
    const DensityEvent e =
        f.strategy->PostBackward(3100, g, &radii, &f.model, &f.adam);
    EXPECT_EQ(e.pruned, 3u);
    EXPECT_EQ(e.parent, (std::vector<int64_t>{3}));
    EXPECT_EQ(f.model.size(), 1u);
    EXPECT_EQ(f.adam.size(), 1u);
    EXPECT_EQ(f.model.means[0], 3.f);
  }
}

TEST(Density, ResetsOpacityAndItsMomentsEvery3000) {
  GaussianModel model = MakeModel(3, 0.001f, 0.5f);
  model.opacity_logits[1] = Logit(0.006f);
  model.opacity_logits[2] = Logit(0.0099f);
  Fixture f(model);
  const GaussianGradients g = Grads(f.model, {0.f, 0.f, 0.f});
  f.adam.Step(g, &f.model);
  const auto logits = f.model.opacity_logits;
  const auto xyz_m = f.adam.state(ParamGroup::kXyz).exp_avg;
  EXPECT_FALSE(f.strategy->PostBackward(2999, g, nullptr, &f.model, &f.adam)
                   .opacity_reset);
  const DensityEvent e =
      f.strategy->PostBackward(3000, g, nullptr, &f.model, &f.adam);
  EXPECT_TRUE(e.opacity_reset);
  EXPECT_NEAR(f.model.opacity_logits[0], Logit(0.01f), 1e-5);
  EXPECT_EQ(f.model.opacity_logits[1], logits[1]);
  EXPECT_EQ(f.model.opacity_logits[2], logits[2]);
  for (float m : f.adam.state(ParamGroup::kOpacity).exp_avg) EXPECT_EQ(m, 0.f);
  EXPECT_EQ(f.adam.state(ParamGroup::kXyz).exp_avg, xyz_m);
  EXPECT_EQ(ResetOpacityLogit(-60.f, 0.01), -60.f);
  EXPECT_TRUE(std::isfinite(ResetOpacityLogit(60.f, 0.01)));
}

TEST(Density, FollowsTheSchedule) {
  Fixture f(MakeModel(2, 0.001f, 0.5f));
  const GaussianGradients g = Grads(f.model, {1e-3f, 1e-3f});
  // Not at densify_from_iter itself, not off the interval, not after 15000.
  for (int64_t it : {500, 650, 15000, 15100}) {
    EXPECT_FALSE(
        f.strategy->PostBackward(it, g, nullptr, &f.model, &f.adam).densified)
        << it;
  }
  EXPECT_TRUE(
      f.strategy->PostBackward(14900, g, nullptr, &f.model, &f.adam).densified);
}

TEST(Density, SavedStateReproducesSplits) {
  DensityOptions options;
  options.seed = 3;
  Fixture a(MakeModel(5, 0.05f, 0.5f), options);
  const GaussianGradients g = Grads(a.model, std::vector<float>(5, 1e-3f));
  a.strategy->PostBackward(599, g, nullptr, &a.model, &a.adam);
  const std::string state = a.strategy->SaveState();
  Fixture b(a.model, options);
  b.strategy->LoadState(state);
  a.strategy->PostBackward(600, g, nullptr, &a.model, &a.adam);
  b.strategy->PostBackward(600, g, nullptr, &b.model, &b.adam);
  EXPECT_EQ(a.model.size(), 10u);
  EXPECT_EQ(a.model.means, b.model.means);
  EXPECT_THROW(b.strategy->LoadState("garbage"), Error);
}

TEST(Density, StateCountBeyondItsBytesIsRefusedBeforeAllocating) {
  Fixture f(MakeModel(5, 0.05f, 0.5f), DensityOptions{});
  std::string state = f.strategy->SaveState();
  // The first vector's element count claims 2^33 floats (32 GiB).
  const uint64_t huge = uint64_t(1) << 33;
  state.replace(0, sizeof(huge), reinterpret_cast<const char*>(&huge),
                sizeof(huge));
  try {
    f.strategy->LoadState(state);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt size"), std::string::npos);
  }
}

}  // namespace
}  // namespace watergs
