// Tests for the Adam optimiser: Inria's learning-rate schedule, the update
// rule against a double-precision reference, frozen groups and masks,
// non-finite gradients, and moment bookkeeping under density control.
#include "gaussian/adam.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <utility>

#include "gaussian/sh.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed) {
  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal;
  for (ParamGroup g :
       {ParamGroup::kXyz, ParamGroup::kFDc, ParamGroup::kFRest,
        ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation}) {
    for (float& v : GroupParams(model, g)) v = normal(rng);
  }
  return model;
}

GaussianGradients RandomGrads(const GaussianModel& model, uint32_t seed) {
  GaussianGradients grads;
  grads.Reset(model.size(), model.sh_rest_stride());
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1e-2f);
  for (auto* v : {&grads.means, &grads.sh_dc, &grads.sh_rest,
                  &grads.opacity_logits, &grads.log_scales, &grads.quats}) {
    for (float& x : *v) x = normal(rng);
  }
  return grads;
}

TEST(Adam, ExponentialLrFollowsInriaSchedule) {
  EXPECT_DOUBLE_EQ(ExponentialLr(0, 1e-2, 1e-4, 0, 0.01, 1000), 1e-2);
  EXPECT_NEAR(ExponentialLr(1000, 1e-2, 1e-4, 0, 0.01, 1000), 1e-4, 1e-18);
  EXPECT_NEAR(ExponentialLr(5000, 1e-2, 1e-4, 0, 0.01, 1000), 1e-4, 1e-18);
  // Log-linear: halfway is the geometric mean.
  EXPECT_NEAR(ExponentialLr(500, 1e-2, 1e-4, 0, 0.01, 1000), 1e-3, 1e-15);
  EXPECT_EQ(ExponentialLr(-1, 1e-2, 1e-4, 0, 0.01, 1000), 0.0);
  // With a delay the rate starts at delay_mult times the curve.
  EXPECT_NEAR(ExponentialLr(0, 1e-2, 1e-4, 100, 0.01, 1000), 1e-4, 1e-18);
  EXPECT_NEAR(ExponentialLr(100, 1e-2, 1e-4, 100, 0.01, 1000),
              ExponentialLr(100, 1e-2, 1e-4, 0, 0.01, 1000), 1e-15);
}

TEST(Adam, PositionRateScalesWithExtentOthersConstant) {
  AdamOptions options;
  options.position_lr_max_steps = 100;
  Adam adam(options, 4.0);
  adam.SetIteration(0);
  EXPECT_NEAR(adam.LearningRate(ParamGroup::kXyz), 1.6e-4 * 4.0, 1e-15);
  adam.SetIteration(100);
  EXPECT_NEAR(adam.LearningRate(ParamGroup::kXyz), 1.6e-6 * 4.0, 1e-17);
  EXPECT_DOUBLE_EQ(adam.LearningRate(ParamGroup::kFDc), 2.5e-3);
  EXPECT_DOUBLE_EQ(adam.LearningRate(ParamGroup::kFRest), 2.5e-3 / 20);
  EXPECT_DOUBLE_EQ(adam.LearningRate(ParamGroup::kOpacity), 0.05);
  EXPECT_DOUBLE_EQ(adam.LearningRate(ParamGroup::kScaling), 5e-3);
  EXPECT_DOUBLE_EQ(adam.LearningRate(ParamGroup::kRotation), 1e-3);
}

// embed --lr_scale: every rate scales, the schedule's shape and Adam's
// constants do not.
TEST(Adam, ScaleRatesScalesEveryRateAndNothingElse) {
  const AdamOptions base;
  AdamOptions scaled = base;
  ScaleRates(0.25, &scaled);
  EXPECT_DOUBLE_EQ(scaled.position_lr_init, 0.25 * base.position_lr_init);
  EXPECT_DOUBLE_EQ(scaled.position_lr_final, 0.25 * base.position_lr_final);
  EXPECT_DOUBLE_EQ(scaled.feature_lr, 0.25 * base.feature_lr);
  EXPECT_DOUBLE_EQ(scaled.feature_rest_lr, 0.25 * base.feature_rest_lr);
  EXPECT_DOUBLE_EQ(scaled.opacity_lr, 0.25 * base.opacity_lr);
  EXPECT_DOUBLE_EQ(scaled.scaling_lr, 0.25 * base.scaling_lr);
  EXPECT_DOUBLE_EQ(scaled.rotation_lr, 0.25 * base.rotation_lr);
  EXPECT_EQ(scaled.position_lr_max_steps, base.position_lr_max_steps);
  EXPECT_EQ(scaled.beta1, base.beta1);
  EXPECT_EQ(scaled.beta2, base.beta2);
  EXPECT_EQ(scaled.eps, base.eps);
}

TEST(Adam, MatchesDoublePrecisionReference) {
  GaussianModel model = RandomModel(7, 1, 1);
  const GaussianModel start = model;
  Adam adam(AdamOptions{}, 2.0);
  adam.Init(model);
  const double b1 = 0.9, b2 = 0.999, eps = 1e-15;
  // Reference state for the opacity and f_rest groups.
  for (ParamGroup group : {ParamGroup::kOpacity, ParamGroup::kFRest}) {
    std::vector<double> p(GroupParams(start, group).begin(),
                          GroupParams(start, group).end());
    std::vector<double> m(p.size(), 0), v(p.size(), 0);
    GaussianModel run = start;
    Adam opt(AdamOptions{}, 2.0);
    opt.Init(run);
    for (int t = 1; t <= 5; ++t) {
      opt.SetIteration(t);
      const GaussianGradients grads = RandomGrads(run, 10 + t);
      opt.Step(grads, &run);
      const double lr = opt.LearningRate(group);
      const auto& g = GroupGrads(grads, group);
      for (size_t j = 0; j < p.size(); ++j) {
        m[j] = b1 * m[j] + (1 - b1) * g[j];
        v[j] = b2 * v[j] + (1 - b2) * double(g[j]) * g[j];
        const double mh = m[j] / (1 - std::pow(b1, t));
        const double vh = v[j] / (1 - std::pow(b2, t));
        p[j] -= lr * mh / (std::sqrt(vh) + eps);
      }
    }
    const auto& got = GroupParams(run, group);
    for (size_t j = 0; j < p.size(); ++j) {
      EXPECT_NEAR(got[j], p[j], 1e-5) << GroupName(group) << " " << j;
    }
  }
  // First step moves every parameter by lr against the gradient's sign.
  adam.SetIteration(1);
  const GaussianGradients grads = RandomGrads(model, 99);
  adam.Step(grads, &model);
  for (size_t j = 0; j < model.means.size(); ++j) {
    const double lr = adam.LearningRate(ParamGroup::kXyz);
    EXPECT_NEAR(model.means[j] - start.means[j],
                -lr * (grads.means[j] > 0 ? 1 : -1), 1e-3 * lr);
  }
}

TEST(Adam, FrozenGroupsAndMaskedGaussiansStayBitIdentical) {
  GaussianModel model = RandomModel(9, 3, 2);
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  adam.SetGroupEnabled(ParamGroup::kFRest, false);
  std::vector<uint8_t> mask(9, 1);
  mask[3] = 0;
  adam.SetGaussianMask(ParamGroup::kXyz, mask);
  // One ordinary step first so that the frozen group's moments are nonzero.
  adam.SetGroupEnabled(ParamGroup::kFRest, true);
  adam.Step(RandomGrads(model, 3), &model);
  adam.SetGroupEnabled(ParamGroup::kFRest, false);
  const GaussianModel before = model;
  const AdamGroupState rest_before = adam.state(ParamGroup::kFRest);
  const std::vector<float> xyz_m = adam.state(ParamGroup::kXyz).exp_avg;
  for (int t = 0; t < 3; ++t) adam.Step(RandomGrads(model, 4 + t), &model);
  EXPECT_EQ(0, std::memcmp(before.sh_rest.data(), model.sh_rest.data(),
                           model.sh_rest.size() * sizeof(float)));
  EXPECT_EQ(rest_before.exp_avg, adam.state(ParamGroup::kFRest).exp_avg);
  EXPECT_EQ(rest_before.exp_avg_sq, adam.state(ParamGroup::kFRest).exp_avg_sq);
  EXPECT_EQ(rest_before.step, adam.state(ParamGroup::kFRest).step);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(before.means[9 + k], model.means[9 + k]);
    EXPECT_EQ(xyz_m[9 + k], adam.state(ParamGroup::kXyz).exp_avg[9 + k]);
    EXPECT_NE(before.means[k], model.means[k]);
  }
  EXPECT_NE(before.sh_dc, model.sh_dc);
}

TEST(Adam, NonFiniteGradientsNeverReachParameters) {
  GaussianModel model = RandomModel(4, 0, 5);
  GaussianModel reference = model;
  Adam adam(AdamOptions{}, 1.0), ref(AdamOptions{}, 1.0);
  adam.Init(model);
  ref.Init(reference);
  GaussianGradients grads = RandomGrads(model, 6);
  GaussianGradients clean = grads;
  grads.means[1] = std::numeric_limits<float>::quiet_NaN();
  grads.opacity_logits[2] = std::numeric_limits<float>::infinity();
  grads.log_scales[0] = -std::numeric_limits<float>::infinity();
  clean.means[1] = 0;
  clean.opacity_logits[2] = 0;
  clean.log_scales[0] = 0;
  EXPECT_EQ(adam.Step(grads, &model), 3u);
  EXPECT_EQ(ref.Step(clean, &reference), 0u);
  EXPECT_EQ(model.CountNonFinite(), 0u);
  EXPECT_EQ(model.means, reference.means);
  EXPECT_EQ(model.opacity_logits, reference.opacity_logits);
  EXPECT_EQ(adam.rejected_total(), 3);
  // Huge finite gradients give a bounded step.
  GaussianGradients huge = clean;
  huge.means[0] = 3e38f;
  adam.Step(huge, &model);
  EXPECT_EQ(model.CountNonFinite(), 0u);
}

TEST(Adam, MomentsFollowFilterAndAppend) {
  GaussianModel model = RandomModel(5, 1, 7);
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  adam.Step(RandomGrads(model, 8), &model);
  const auto before = adam.state(ParamGroup::kRotation).exp_avg;
  const std::vector<bool> keep = {true, false, true, false, true};
  adam.Filter(keep);
  ASSERT_EQ(adam.size(), 3u);
  const auto& after = adam.state(ParamGroup::kRotation).exp_avg;
  ASSERT_EQ(after.size(), 12u);
  const int kept[3] = {0, 2, 4};
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(after[i * 4 + k], before[kept[i] * 4 + k]);
    }
  }
  adam.Append(2);
  ASSERT_EQ(adam.size(), 5u);
  const auto& grown = adam.state(ParamGroup::kFRest).exp_avg_sq;
  ASSERT_EQ(grown.size(), 5u * 9);
  for (size_t j = 3 * 9; j < grown.size(); ++j) EXPECT_EQ(grown[j], 0.f);
  EXPECT_GT(std::abs(grown[0]), 0.f);
  adam.ResetMoments(ParamGroup::kOpacity);
  for (float m : adam.state(ParamGroup::kOpacity).exp_avg) EXPECT_EQ(m, 0.f);
  EXPECT_EQ(adam.state(ParamGroup::kOpacity).step, 1);
}

TEST(Adam, MismatchedGradientsAreAnError) {
  GaussianModel model = RandomModel(3, 0, 9);
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  GaussianGradients grads;
  grads.Reset(2, 0);
  EXPECT_THROW(adam.Step(grads, &model), Error);
}

}  // namespace
}  // namespace watergs

namespace watergs {
namespace {

TEST(CompactAdam, MomentCodeRoundTripsWithinOneSixteenth) {
  for (float x = std::ldexp(1.07f, -8); x < 240.f; x *= 1.013f) {
    for (float s : {1.f, -1.f}) {
      const float back = DecodeMomentCode(EncodeMomentCode(s * x));
      EXPECT_LE(std::abs(back - s * x), x / 16 + 1e-12f) << x;
      EXPECT_EQ(back < 0, s < 0);
    }
  }
  EXPECT_EQ(DecodeMomentCode(EncodeMomentCode(0.f)), 0.f);
  EXPECT_EQ(DecodeMomentCode(EncodeMomentCode(1e-4f)), 0.f);
  EXPECT_EQ(DecodeMomentCode(EncodeMomentCode(1e9f)), 240.f);
  EXPECT_EQ(DecodeMomentCode(EncodeMomentCode(std::nanf(""))), 0.f);
  // A momentum that only decays (beta1 = 0.9, zero gradients) reaches 0.
  float m = 3.f;
  for (int t = 0; t < 200; ++t)
    m = DecodeMomentCode(EncodeMomentCode(0.9f * m));
  EXPECT_EQ(m, 0.f);
}

TEST(CompactAdam, FirstStepNormalisesByTheGroupRms) {
  GaussianModel model = RandomModel(6, 1, 11);
  const GaussianModel start = model;
  AdamOptions options;
  options.compact_moments = true;
  Adam adam(options, 1.0);
  adam.Init(model);
  EXPECT_EQ(adam.BytesPerGaussian(), size_t(3 + 3 + 9 + 1 + 3 + 4) + 6 * 4);
  adam.SetIteration(1);
  const GaussianGradients grads = RandomGrads(model, 12);
  adam.Step(grads, &model);
  // m_hat / sqrt(v_hat) = g / rms(g over the Gaussian's group values).
  const double lr = adam.LearningRate(ParamGroup::kFRest);
  for (size_t i = 0; i < 6; ++i) {
    double mean_sq = 0;
    for (int k = 0; k < 9; ++k)
      mean_sq += std::pow(grads.sh_rest[9 * i + k], 2) / 9;
    for (int k = 0; k < 9; ++k) {
      const size_t j = 9 * i + k;
      EXPECT_NEAR(model.sh_rest[j] - start.sh_rest[j],
                  -lr * grads.sh_rest[j] / std::sqrt(mean_sq), 1e-3 * lr);
    }
  }
}

// Minimises sum_j a_j (p_j - c_j)^2 over every group, from RandomModel(n,
// degree, seed) to RandomModel(n, degree, seed + 1), all rates `lr`;
// returns the loss at the first and at the last step.
std::pair<double, double> MinimiseQuadratic(AdamOptions options, size_t n,
                                            int degree, uint32_t seed,
                                            double lr, int steps) {
  GaussianModel model = RandomModel(n, degree, seed);
  const GaussianModel target = RandomModel(n, degree, seed + 1);
  options.position_lr_init = options.position_lr_final = lr;
  options.feature_lr = options.feature_rest_lr = options.opacity_lr = lr;
  options.scaling_lr = options.rotation_lr = lr;
  Adam adam(options, 1.0);
  adam.Init(model);
  GaussianGradients grads;
  double loss = 0, initial = 0;
  for (int t = 1; t <= steps; ++t) {
    adam.SetIteration(t);
    grads.Reset(model.size(), model.sh_rest_stride());
    loss = 0;
    for (ParamGroup g :
         {ParamGroup::kXyz, ParamGroup::kFDc, ParamGroup::kFRest,
          ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation}) {
      auto& p = GroupParams(model, g);
      const auto& c = GroupParams(target, g);
      auto& d = const_cast<std::vector<float>&>(GroupGrads(grads, g));
      for (size_t j = 0; j < p.size(); ++j) {
        const double a = 1 + j % 5;
        loss += a * (p[j] - c[j]) * (p[j] - c[j]);
        d[j] = float(2 * a * (p[j] - c[j]));
      }
    }
    if (t == 1) initial = loss;
    adam.Step(grads, &model);
  }
  return {initial, loss};
}

TEST(CompactAdam, ConvergesLikeFullAdamOnAQuadratic) {
  AdamOptions compact_options;
  compact_options.compact_moments = true;
  const auto [initial, full] =
      MinimiseQuadratic(AdamOptions{}, 20, 2, 13, 0.02, 1500);
  const auto [initial_compact, compact] =
      MinimiseQuadratic(compact_options, 20, 2, 13, 0.02, 1500);
  EXPECT_EQ(initial, initial_compact);
  EXPECT_LT(full, 1e-3 * initial);
  EXPECT_LT(compact, 1e-3 * initial);
  EXPECT_LT(compact, 3 * full + 1e-4 * initial);
}

TEST(CompactAdam, MomentsFollowFilterAppendAndMasks) {
  GaussianModel model = RandomModel(5, 1, 15);
  AdamOptions options;
  options.compact_moments = true;
  Adam adam(options, 1.0);
  adam.Init(model);
  std::vector<uint8_t> mask = {1, 0, 1, 1, 1};
  adam.SetGaussianMask(ParamGroup::kFDc, mask);
  const GaussianModel before = model;
  adam.Step(RandomGrads(model, 16), &model);
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(model.sh_dc[3 + k], before.sh_dc[3 + k]);
  EXPECT_EQ(adam.state(ParamGroup::kFDc).exp_avg_sq_shared[1], 0.f);
  const auto q = adam.state(ParamGroup::kFRest).exp_avg_q;
  const auto v = adam.state(ParamGroup::kFRest).exp_avg_sq_shared;
  adam.Filter({false, true, true, false, true});
  adam.Append(1);
  const auto& q2 = adam.state(ParamGroup::kFRest).exp_avg_q;
  const auto& v2 = adam.state(ParamGroup::kFRest).exp_avg_sq_shared;
  ASSERT_EQ(q2.size(), 4u * 9);
  ASSERT_EQ(v2.size(), 4u);
  EXPECT_EQ(v2[0], v[1]);
  EXPECT_EQ(v2[2], v[4]);
  EXPECT_EQ(v2[3], 0.f);
  for (int k = 0; k < 9; ++k) {
    EXPECT_EQ(q2[9 + k], q[18 + k]);
    EXPECT_EQ(q2[27 + k], 0);
  }
}

}  // namespace
}  // namespace watergs

namespace watergs {
namespace {

// bfloat16 bits -> float, independent of the optimiser's own decoder.
float FromBf16(uint16_t bits) {
  const uint32_t wide = static_cast<uint32_t>(bits) << 16;
  float x;
  std::memcpy(&x, &wide, sizeof(x));
  return x;
}

TEST(HalfMomentAdam, SecondMomentTracksItsEmaThroughStochasticRounding) {
  // A constant gradient g: v_t = g^2 (1 - 0.999^t). Each step adds 0.1% of v,
  // under bfloat16's 0.4-0.8% spacing: round-to-nearest would freeze v near
  // its early value, stochastic rounding follows the curve on average.
  GaussianModel model = RandomModel(64, 0, 21);
  AdamOptions options;
  options.half_moments = true;
  Adam adam(options, 1.0);
  adam.Init(model);
  GaussianGradients grads;
  grads.Reset(model.size(), model.sh_rest_stride());
  std::fill(grads.opacity_logits.begin(), grads.opacity_logits.end(), 0.3f);
  const int steps = 3000;
  for (int t = 1; t <= steps; ++t) adam.Step(grads, &model);
  const double expected = 0.09 * (1 - std::pow(0.999, steps));
  const auto& v = adam.state(ParamGroup::kOpacity).exp_avg_sq_h;
  ASSERT_EQ(v.size(), 64u);
  double mean = 0;
  for (uint16_t bits : v) mean += FromBf16(bits) / v.size();
  EXPECT_NEAR(mean, expected, 0.01 * expected);
  // Positions keep float moments.
  EXPECT_TRUE(adam.state(ParamGroup::kXyz).exp_avg_h.empty());
  EXPECT_EQ(adam.state(ParamGroup::kXyz).exp_avg_sq.size(), 3u * 64);
}

TEST(HalfMomentAdam, ConvergesLikeFloatAdamOnAQuadratic) {
  AdamOptions half_options;
  half_options.half_moments = true;
  const double full =
      MinimiseQuadratic(AdamOptions{}, 40, 3, 23, 0.01, 1500).second;
  const double half =
      MinimiseQuadratic(half_options, 40, 3, 23, 0.01, 1500).second;
  EXPECT_LT(full, 1e-3);
  EXPECT_LT(half, 3 * full + 1e-4);
}

TEST(HalfMomentAdam, MomentsFollowFilterAppendAndResumeBitIdentically) {
  GaussianModel model = RandomModel(5, 1, 25);
  AdamOptions options;
  options.half_moments = true;
  Adam adam(options, 1.0);
  adam.Init(model);
  adam.Step(RandomGrads(model, 26), &model);
  const auto m = adam.state(ParamGroup::kFRest).exp_avg_h;
  ASSERT_EQ(m.size(), 5u * 9);
  adam.Filter({false, true, true, false, true});
  adam.Append(1);
  const auto& m2 = adam.state(ParamGroup::kFRest).exp_avg_h;
  ASSERT_EQ(m2.size(), 4u * 9);
  for (int k = 0; k < 9; ++k) {
    EXPECT_EQ(m2[k], m[9 + k]);
    EXPECT_EQ(m2[18 + k], m[36 + k]);
    EXPECT_EQ(m2[27 + k], 0);
  }
  // A copy of the state continues exactly as the original (the rounding
  // stream depends on the step and block, not on hidden generator state).
  model.Resize(4);
  Adam copy = adam;
  GaussianModel model_copy = model;
  const GaussianGradients grads = RandomGrads(model, 27);
  adam.Step(grads, &model);
  copy.Step(grads, &model_copy);
  EXPECT_EQ(model.sh_rest, model_copy.sh_rest);
  EXPECT_EQ(adam.state(ParamGroup::kFRest).exp_avg_sq_h,
            copy.state(ParamGroup::kFRest).exp_avg_sq_h);
}

TEST(Adam, FactoredShGradientsGiveTheDenseUpdate) {
  // The same step from dense SH gradients and from their factors.
  GaussianModel model = RandomModel(30, 3, 28);
  std::mt19937 rng(29);
  std::normal_distribution<float> normal(0.f, 1e-2f);
  GaussianGradients factored = RandomGrads(model, 30);
  factored.compact_sh = true;
  factored.sh_active_degree = 2;
  factored.sh_color_grad.resize(3 * model.size());
  factored.sh_view_dir.resize(3 * model.size());
  for (float& x : factored.sh_color_grad) x = normal(rng);
  for (float& x : factored.sh_view_dir) x = 100 * normal(rng);
  factored.sh_view_dir[0] = factored.sh_view_dir[1] = factored.sh_view_dir[2] =
      0.f;  // degenerate direction
  GaussianGradients dense = factored;
  dense.compact_sh = false;
  dense.sh_dc.resize(3 * model.size());
  dense.sh_rest.resize(model.size() * model.sh_rest_stride());
  for (size_t i = 0; i < model.size(); ++i) {
    ShCoefficientGradients(2, &factored.sh_view_dir[3 * i],
                           &factored.sh_color_grad[3 * i],
                           model.sh_rest_stride(), &dense.sh_dc[3 * i],
                           &dense.sh_rest[i * model.sh_rest_stride()]);
  }
  // Degree 2 leaves the degree-3 coefficients without gradient.
  EXPECT_EQ(dense.sh_rest[model.sh_rest_stride() - 1], 0.f);
  EXPECT_NE(dense.sh_rest[model.sh_rest_stride() + 3 * 3], 0.f);
  for (bool half : {false, true}) {
    AdamOptions options;
    options.half_moments = half;
    Adam a(options, 1.0), b(options, 1.0);
    a.Init(model);
    b.Init(model);
    GaussianModel from_dense = model, from_factors = model;
    a.Step(dense, &from_dense);
    b.Step(factored, &from_factors);
    EXPECT_EQ(from_dense.sh_dc, from_factors.sh_dc);
    EXPECT_EQ(from_dense.sh_rest, from_factors.sh_rest);
    EXPECT_EQ(from_dense.means, from_factors.means);
  }
}

}  // namespace
}  // namespace watergs
