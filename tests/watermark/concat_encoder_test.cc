// Tests of the CONCAT + 3DGS baseline's encoder: the MLP's gradients against
// finite differences (double), the gradient through the rasterizer and the
// decoder (float), the zero-initialised encoder being the identity, training
// on a tiny synthetic scene lowering the message loss, frozen attributes
// staying bit-identical, and non-finite or mismatched input refused.
#include "watermark/concat_encoder.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gaussian/util/error.h"
#include "tests/common/embed_scene.h"
#include "watermark/embedder.h"

namespace watergs {
namespace {

using testing::MakeResponsive;
using testing::MakeScene;
using testing::RandomBall;
using testing::RandomBits;
using testing::Scene;
using testing::TinyDecoderConfig;

// Arrays of one MLP in double, with views for the MLP functions.
struct DoubleMlp {
  int coeffs, bits, hidden;
  std::vector<double> w1, b1, w2, b2;
  DoubleMlp(int c, int l, int h)
      : coeffs(c),
        bits(l),
        hidden(h),
        w1(size_t(h) * (c + l)),
        b1(h),
        w2(size_t(c) * h),
        b2(c) {}
  ConcatMlpWeights<double> View() {
    return {coeffs, bits, hidden, w1, b1, w2, b2};
  }
  ConcatMlpWeights<const double> ConstView() {
    return {coeffs, bits, hidden, w1, b1, w2, b2};
  }
};

// sum(c .* offsets) for fixed c: its gradient w.r.t. the offsets is c.
double WeightedOutput(DoubleMlp& mlp, const std::vector<double>& inputs,
                      const std::vector<double>& signs,
                      const std::vector<double>& c) {
  std::vector<double> offsets, hidden;
  ConcatMlpForward<double>(mlp.ConstView(), inputs, signs, &offsets, &hidden);
  double sum = 0;
  for (size_t k = 0; k < c.size(); ++k) sum += c[k] * offsets[k];
  return sum;
}

// Every weight's gradient against a central difference in double. The
// function is piecewise linear in each weight, so away from a ReLU kink the
// difference is exact up to rounding (~1e-16 / eps = 1e-10); a kink within
// eps of a unit's pre-activation would show as an O(1) error. Tolerance
// 1e-7 is far above rounding and far below any indexing error.
TEST(ConcatMlp, WeightGradientsMatchFiniteDifferencesInDouble) {
  const int n = 6, coeffs = 5, bits = 4, hidden = 7;
  DoubleMlp mlp(coeffs, bits, hidden);
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0, 1);
  for (auto* v : {&mlp.w1, &mlp.b1, &mlp.w2, &mlp.b2}) {
    for (double& x : *v) x = normal(rng);
  }
  std::vector<double> inputs(n * coeffs), c(n * coeffs);
  for (double& x : inputs) x = normal(rng);
  for (double& x : c) x = normal(rng);
  const std::vector<double> signs = {1, -1, -1, 1};

  std::vector<double> offsets, hidden_act;
  ConcatMlpForward<double>(mlp.ConstView(), inputs, signs, &offsets,
                           &hidden_act);
  int active = 0;
  for (double h : hidden_act) active += h > 0;
  // Both ReLU branches are exercised.
  ASSERT_GT(active, 5);
  ASSERT_LT(active, n * hidden - 5);

  DoubleMlp grads(coeffs, bits, hidden);
  ConcatMlpBackward<double>(mlp.ConstView(), inputs, signs, hidden_act, c,
                            grads.View());
  const double eps = 1e-6;
  std::vector<double>* params[] = {&mlp.w1, &mlp.b1, &mlp.w2, &mlp.b2};
  std::vector<double>* analytic[] = {&grads.w1, &grads.b1, &grads.w2,
                                     &grads.b2};
  for (int p = 0; p < 4; ++p) {
    for (size_t k = 0; k < params[p]->size(); ++k) {
      const double saved = (*params[p])[k];
      (*params[p])[k] = saved + eps;
      const double up = WeightedOutput(mlp, inputs, signs, c);
      (*params[p])[k] = saved - eps;
      const double down = WeightedOutput(mlp, inputs, signs, c);
      (*params[p])[k] = saved;
      EXPECT_NEAR((up - down) / (2 * eps), (*analytic[p])[k], 1e-7)
          << "parameter " << p << " entry " << k;
    }
  }
}

// The gradients must not depend on where the buffers lie in memory: an
// Eigen reduction evaluated straight into an unaligned buffer sums some
// entries in SIMD packets and the rest one by one by the buffer's address,
// which made repeated concat_embed runs differ in the last bits. The grads
// (and the upstream gradient) are placed at every float offset within a
// 64-byte line; 48 coefficients (an SH degree 3 "sh" target) span whole
// AVX-512 packets plus a tail. Results must be bit-identical.
TEST(ConcatMlp, GradientsDoNotDependOnBufferAlignment) {
  const int n = 300, coeffs = 48, bits = 32, hidden = 64;
  std::mt19937 rng(4);
  std::normal_distribution<float> normal(0, 1);
  auto random = [&](size_t size) {
    std::vector<float> v(size);
    for (float& x : v) x = normal(rng);
    return v;
  };
  const std::vector<float> w1 = random(size_t(hidden) * (coeffs + bits)),
                           b1 = random(hidden), w2 = random(coeffs * hidden),
                           b2 = random(coeffs), inputs = random(n * coeffs),
                           doffsets = random(n * coeffs);
  std::vector<float> signs(bits);
  for (int k = 0; k < bits; ++k) signs[k] = k % 3 ? 1.f : -1.f;
  const ConcatMlpWeights<const float> w{coeffs, bits, hidden, w1, b1, w2, b2};
  std::vector<float> offsets, hidden_act;
  ConcatMlpForward<float>(w, inputs, signs, &offsets, &hidden_act);
  const size_t sizes[] = {w1.size(), b1.size(), w2.size(), b2.size()};
  const size_t total = w1.size() + b1.size() + w2.size() + b2.size();
  std::vector<float> first;
  for (int shift = 0; shift < 16; ++shift) {
    // Over-allocated Eigen vectors are 64-byte aligned; `shift` floats in.
    Eigen::VectorXf grads = Eigen::VectorXf::Zero(total + 16);
    Eigen::VectorXf dout(doffsets.size() + 16);
    std::copy(doffsets.begin(), doffsets.end(), dout.data() + shift);
    float* g[4];
    g[0] = grads.data() + shift;
    for (int k = 1; k < 4; ++k) g[k] = g[k - 1] + sizes[k - 1];
    const ConcatMlpWeights<float> view{coeffs,           bits,
                                       hidden,           {g[0], sizes[0]},
                                       {g[1], sizes[1]}, {g[2], sizes[2]},
                                       {g[3], sizes[3]}};
    ConcatMlpBackward<float>(
        w, inputs, signs, hidden_act,
        std::span<const float>(dout.data() + shift, doffsets.size()), view);
    const std::vector<float> result(g[0], g[0] + total);
    if (shift == 0) first = result;
    EXPECT_EQ(result, first) << "grads " << shift << " floats off alignment";
  }
}

TEST(ConcatEncoder, ParsesTargetsAndRejectsBadOnes) {
  const ShTarget dc = ParseShTarget("f_dc");
  EXPECT_TRUE(dc.dc && !dc.rest);
  const ShTarget rest = ParseShTarget("f_rest");
  EXPECT_TRUE(!rest.dc && rest.rest);
  for (const char* both : {"sh", "f_dc,f_rest"}) {
    const ShTarget t = ParseShTarget(both);
    EXPECT_TRUE(t.dc && t.rest) << both;
    EXPECT_EQ(t.NumCoeffs(3), 48) << both;
  }
  EXPECT_THROW(ParseShTarget("xyz"), Error);
  EXPECT_THROW(ParseShTarget(""), Error);
  // A degree-0 model has no f_rest to write.
  EXPECT_THROW(ConcatEncoder(rest, 0, 8, 4, 1), Error);
  EXPECT_THROW(ConcatEncoder(dc, 1, 8, 0, 1), Error);
}

TEST(ConcatEncoder, StartsAsTheIdentity) {
  const GaussianModel model = RandomBall(30, 4, 0.1f);
  const ConcatEncoder encoder(ParseShTarget("sh"), model.sh_degree, 8, 16, 2);
  for (uint32_t seed : {1u, 2u, 3u}) {
    const GaussianModel out = encoder.Apply(model, RandomBits(8, seed));
    EXPECT_EQ(out.sh_dc, model.sh_dc);
    EXPECT_EQ(out.sh_rest, model.sh_rest);
    EXPECT_EQ(out.means, model.means);
  }
}

// Sets E's last layer to small random values (a zero one passes no gradient
// to the first layer).
void RandomiseLastLayer(ConcatEncoder* encoder, float scale, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0, scale);
  for (Parameter* p : encoder->Parameters()) {
    if (p->name.rfind("concat.fc2", 0) == 0) {
      for (float& x : p->value) x = normal(rng);
    }
  }
}

// The chain rasterizer -> encoder (gathering visible rows, packing f_dc and
// f_rest) in float: the derivative along the normalised gradient must equal
// its norm. Tolerance as the embedder's message-gradient test: float
// rounding of a ~0.7 loss divided by 2 eps gives ~1e-3 absolute; a wrong
// packing order or row changes the derivative by O(1) of the norm.
TEST(ConcatEncoder, GradientThroughTheRasterizerMatchesFiniteDifferences) {
  Scene s = MakeScene(1, 28, 22);
  HiddenModel net(TinyDecoderConfig(8), false, 11);
  Decoder decoder(&net);
  auto rasterizer = MakeCpuRasterizer();
  const Bits message = RandomBits(8, 5);
  ConcatEncoder encoder(ParseShTarget("sh"), s.model.sh_degree, 8, 12, 3);
  RandomiseLastLayer(&encoder, 0.05f, 9);
  RenderOptions options;
  options.rect = PixelRect{5, 4, 16, 14};
  const RenderCamera cam = s.views.Camera(0);

  GaussianModel encoded;
  encoder.Apply(s.model, message, &encoded);
  const std::vector<float> targets(message.begin(), message.end());
  GaussianGradients grads;
  MessageLossGradient(*rasterizer, encoded, cam, options, PixelRect{}, decoder,
                      targets, 1.0, &grads);
  for (Parameter* p : encoder.Parameters()) {
    std::fill(p->grad.begin(), p->grad.end(), 0.f);
  }
  encoder.Backward(s.model, message, grads);
  double norm2 = 0;
  for (Parameter* p : encoder.Parameters()) {
    for (float g : p->grad) norm2 += double(g) * g;
  }
  const double norm = std::sqrt(norm2);
  ASSERT_GT(norm, 1e-3);
  const float eps = 2e-3f;
  auto shifted = [&](float sign) {
    ConcatEncoder moved = encoder;
    for (Parameter* p : moved.Parameters()) {
      for (size_t k = 0; k < p->size(); ++k) {
        p->value[k] += sign * eps * p->grad[k] / float(norm);
      }
    }
    return MessageLossGradient(*rasterizer, moved.Apply(s.model, message), cam,
                               options, PixelRect{}, decoder, targets, 1.0,
                               nullptr);
  };
  const double fd = (shifted(1) - shifted(-1)) / (2.0 * eps);
  EXPECT_NEAR(fd, norm, 0.02 * norm + 1e-3);
}

// BCE and BER of whole-frame renders of the encoded model, averaged over
// the views and a fixed set of messages.
struct MessageFigures {
  double bce = 0, ber = 0;
};
MessageFigures MeanMessageFigures(const ConcatEncoder& encoder, const Scene& s,
                                  Decoder& decoder, Rasterizer& rasterizer) {
  MessageFigures f;
  const int num_messages = 6, bits = encoder.num_bits();
  const double count = num_messages * s.views.NumViews();
  ImageRGB image;
  for (int k = 0; k < num_messages; ++k) {
    const Bits message = RandomBits(bits, 100 + k);
    const GaussianModel encoded = encoder.Apply(s.model, message);
    for (size_t v = 0; v < s.views.NumViews(); ++v) {
      rasterizer.Forward(encoded, s.views.Camera(v), RenderOptions{}, &image,
                         nullptr);
      std::vector<float> dlogits;
      int errors = 0;
      f.bce += MessageBce(decoder.Logits(image),
                          std::vector<float>(message.begin(), message.end()),
                          1.0, &dlogits, &errors) /
               count;
      f.ber += double(errors) / bits / count;
    }
  }
  return f;
}

TEST(ConcatEncoderTrainer, TrainingLowersTheMessageLoss) {
  Scene s = MakeScene(2, 32, 24);
  HiddenModel net(TinyDecoderConfig(8), false, 5);
  MakeResponsive(&net, 1000.f, s.views);
  Decoder decoder(&net);
  auto rasterizer = MakeCpuRasterizer();
  ConcatEncoder encoder(ParseShTarget("f_dc"), s.model.sh_degree, 8, 16, 7);
  const MessageFigures before =
      MeanMessageFigures(encoder, s, decoder, *rasterizer);
  ConcatTrainOptions o;
  o.iterations = 300;
  o.gamma = 3;
  o.learning_rate = 1e-2;
  // Whole frames: a random decoder does not read crops and frames alike.
  o.crop_size = 0;
  const ConcatStepStats last = TrainConcatEncoder(
      o, s.views, s.train, s.model, &decoder, rasterizer.get(), &encoder);
  EXPECT_EQ(last.iteration, o.iterations);
  EXPECT_TRUE(std::isfinite(last.total));
  const MessageFigures after =
      MeanMessageFigures(encoder, s, decoder, *rasterizer);
  // Untrained, E is the identity: every message renders the same image,
  // which the centred decoder reads at chance.
  EXPECT_NEAR(before.bce, std::log(2.0), 0.01);
  EXPECT_NEAR(before.ber, 0.5, 0.1);
  // Training must take the loss clearly below chance (here by a tenth of
  // ln 2; a sign or indexing error leaves it at chance or above) and read
  // more bits right. The random decoder's bits share features, so this tiny
  // encoder cannot set all 8 independently (it reaches BER ~1/3).
  EXPECT_LT(after.bce, 0.9 * std::log(2.0))
      << "BCE " << before.bce << " -> " << after.bce;
  EXPECT_LT(after.ber, 0.45) << "BER " << before.ber << " -> " << after.ber;

  // Only f_dc moves; everything else is bit-identical.
  const GaussianModel out = encoder.Apply(s.model, RandomBits(8, 1));
  EXPECT_NE(out.sh_dc, s.model.sh_dc);
  EXPECT_EQ(out.sh_rest, s.model.sh_rest);
  EXPECT_EQ(out.means, s.model.means);
  EXPECT_EQ(out.log_scales, s.model.log_scales);
  EXPECT_EQ(out.quats, s.model.quats);
  EXPECT_EQ(out.opacity_logits, s.model.opacity_logits);
}

TEST(ConcatEncoder, FRestTargetKeepsFDcBitIdentical) {
  const GaussianModel model = RandomBall(30, 4, 0.1f);
  ConcatEncoder encoder(ParseShTarget("f_rest"), model.sh_degree, 8, 16, 2);
  RandomiseLastLayer(&encoder, 0.1f, 3);
  const GaussianModel out = encoder.Apply(model, RandomBits(8, 1));
  EXPECT_NE(out.sh_rest, model.sh_rest);
  EXPECT_EQ(out.sh_dc, model.sh_dc);
  EXPECT_EQ(out.opacity_logits, model.opacity_logits);
  // Another message gives other offsets.
  EXPECT_NE(encoder.Apply(model, RandomBits(8, 2)).sh_rest, out.sh_rest);
}

TEST(ConcatEncoder, RefusesNonFiniteAndMismatchedInput) {
  Scene s = MakeScene(1, 16, 12);
  HiddenModel net(TinyDecoderConfig(8), false, 5);
  Decoder decoder(&net);
  auto rasterizer = MakeCpuRasterizer();
  ConcatEncoder encoder(ParseShTarget("f_dc"), s.model.sh_degree, 8, 4, 7);
  GaussianModel bad = s.model;
  bad.sh_dc[4] = std::nanf("");
  EXPECT_THROW(encoder.Apply(bad, RandomBits(8, 1)), Error);
  // A NaN outside the target groups is refused too (it would render NaN).
  bad = s.model;
  bad.means[1] = INFINITY;
  EXPECT_THROW(encoder.Apply(bad, RandomBits(8, 1)), Error);
  EXPECT_THROW(ConcatEncoderTrainer(ConcatTrainOptions{}, s.views, s.train, bad,
                                    &decoder, rasterizer.get(), &encoder),
               Error);
  // Wrong message length, SH degree or decoder length.
  EXPECT_THROW(encoder.Apply(s.model, RandomBits(7, 1)), Error);
  GaussianModel degree0 = RandomBall(5, 1, 0.1f);
  degree0.sh_degree = 0;
  degree0.sh_rest.clear();
  EXPECT_THROW(encoder.Apply(degree0, RandomBits(8, 1)), Error);
  HiddenModel net16(TinyDecoderConfig(16), false, 5);
  Decoder decoder16(&net16);
  EXPECT_THROW(
      ConcatEncoderTrainer(ConcatTrainOptions{}, s.views, s.train, s.model,
                           &decoder16, rasterizer.get(), &encoder),
      Error);
}

}  // namespace
}  // namespace watergs
