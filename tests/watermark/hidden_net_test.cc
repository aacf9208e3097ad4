// Checks the wiring of the HiDDeN encoder and decoder and the frozen decoder
// path: directional derivatives of whole networks against central finite
// differences (double accumulation, float networks), and the properties the
// embedding relies on (no weight gradients, any image size, caching).
#include "watermark/hidden_net.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include "watermark/decoder.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

HiddenConfig TinyConfig() {
  HiddenConfig config;
  config.num_bits = 8;
  config.channels = 5;
  config.encoder_blocks = 2;
  config.decoder_blocks = 3;
  return config;
}

std::vector<float> RandomVector(size_t n, std::mt19937* rng) {
  std::normal_distribution<float> dist(0.f, 1.f);
  std::vector<float> v(n);
  for (float& x : v) x = dist(*rng);
  return v;
}

double Dot(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += double(a[i]) * b[i];
  return s;
}

// The networks run in float and are piecewise linear (ReLU), so a finite
// difference is limited by rounding and by kinks crossed within the step; a
// wiring error (wrong tensor, missing term) changes the result by O(100%),
// so a 10% band separates the two. Each layer alone is checked in double in
// nn_layers_test.cc.
constexpr float kStep = 1e-4f;
constexpr double kTolerance = 0.1;
// Step of the per-parameter weight checks. Some groups have small
// derivatives (~0.01-0.02 for the first encoder block's biases and
// BatchNorm scale) against a float loss of ~10: at kStep the quotient was
// off by up to 2.4e-3 there, 10-20% of the derivative; at 1e-3 the rounding
// term is ten times less (at most 2.7% of any group's derivative on these
// seeds), and a move of 1e-3 along a handful of values crosses few ReLU
// kinks.
constexpr float kWeightStep = 1e-3f;

// A unit direction whose derivative is far from zero whatever the seed: the
// normalised analytic gradient g plus half a random unit vector orthogonal to
// it. A correct g predicts |g| along it; an error in g along either part
// shows. (A purely random direction over hundreds of inputs can cancel to a
// derivative below float finite-difference noise.)
std::vector<float> WellConditionedDirection(const std::vector<float>& g,
                                            std::mt19937* rng) {
  std::vector<float> r = RandomVector(g.size(), rng);
  const double gg = Dot(g, g), rg = Dot(r, g);
  for (size_t i = 0; i < r.size(); ++i) r[i] -= float(rg / gg) * g[i];
  const double g_norm = std::sqrt(gg), r_norm = std::sqrt(Dot(r, r));
  // (A one-value parameter has no orthogonal part.)
  const double r_scale = r_norm > 0 ? 0.5 / r_norm : 0.0;
  std::vector<float> d(g.size());
  for (size_t i = 0; i < d.size(); ++i)
    d[i] = float(g[i] / g_norm + r_scale * r[i]);
  return d;
}

// (f(+h) - f(-h)) / 2h after `perturb(t)` moves the inputs by t * direction.
double Directional(const std::function<void(float)>& perturb,
                   const std::function<double()>& f, float h) {
  perturb(h);
  const double plus = f();
  perturb(-2 * h);
  const double minus = f();
  perturb(h);
  return (plus - minus) / (2.0 * h);
}

// Weight gradients one parameter at a time: for each trainable parameter
// (a layer's weights, its bias, a BatchNorm scale or shift), its analytic
// gradient (already in p->grad) against a central difference of `loss`
// along a direction confined to that parameter. One direction over all
// weights at once would weigh each group by its share of the whole
// derivative, so an error confined to a small group (a wrong bias gradient,
// a BatchNorm term) could stay inside the tolerance.
void ExpectEachParameterGradient(const std::vector<Parameter*>& params,
                                 const std::function<double()>& loss,
                                 std::mt19937* rng) {
  int checked = 0;
  for (Parameter* p : params) {
    if (!p->trainable) continue;
    SCOPED_TRACE(p->name);
    const std::vector<float> g = p->grad;
    ASSERT_GT(Dot(g, g), 0.0) << "no gradient";
    const std::vector<float> d = WellConditionedDirection(g, rng);
    // Set from the saved values (not moved back and forth), so that the
    // parameter is exactly restored for the next one.
    const std::vector<float> saved = p->value;
    auto set = [&](float t) {
      for (size_t i = 0; i < d.size(); ++i) p->value[i] = saved[i] + t * d[i];
    };
    set(kWeightStep);
    const double plus = loss();
    set(-kWeightStep);
    const double minus = loss();
    p->value = saved;
    const double numeric = (plus - minus) / (2.0 * kWeightStep);
    EXPECT_NEAR(Dot(g, d), numeric, kTolerance * std::abs(numeric) + 1e-5);
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(HiddenDecoderTest, InputGradientMatchesFiniteDifferencesBothModes) {
  for (bool training : {false, true}) {
    std::mt19937 rng(21);
    HiddenModel model(TinyConfig(), false, 4);
    Tensor image(2, 3, 12, 11);
    image.data = RandomVector(image.size(), &rng);
    const std::vector<float> w = RandomVector(2 * 8, &rng);
    Tensor dlogits(2, 8, 1, 1), dimage;
    dlogits.data = w;
    model.decoder->Forward(image, training);
    model.decoder->Backward(dlogits, &dimage, true, training);
    ASSERT_GT(Dot(dimage.data, dimage.data), 1e-8) << "no input gradient";
    const std::vector<float> direction =
        WellConditionedDirection(dimage.data, &rng);
    auto loss = [&] {
      return Dot(model.decoder->Forward(image, training).data, w);
    };
    auto perturb = [&](float t) {
      for (size_t i = 0; i < image.size(); ++i)
        image.data[i] += t * direction[i];
    };
    const double numeric = Directional(perturb, loss, kStep);
    EXPECT_NEAR(Dot(dimage.data, direction), numeric,
                kTolerance * std::abs(numeric) + 1e-5)
        << (training ? "training" : "inference");
  }
}

TEST(HiddenDecoderTest, WeightGradientsMatchFiniteDifferences) {
  std::mt19937 rng(22);
  HiddenModel model(TinyConfig(), false, 5);
  Tensor image(2, 3, 6, 6);
  image.data = RandomVector(image.size(), &rng);
  const std::vector<float> w = RandomVector(16, &rng);
  Tensor dlogits(2, 8, 1, 1), dimage;
  dlogits.data = w;
  std::vector<Parameter*> params = model.DecoderParameters();
  model.decoder->Forward(image, false);
  model.decoder->Backward(dlogits, nullptr, true, false);
  auto loss = [&] { return Dot(model.decoder->Forward(image, false).data, w); };
  ExpectEachParameterGradient(params, loss, &rng);
}

TEST(HiddenEncoderTest, WeightGradientsMatchFiniteDifferences) {
  std::mt19937 rng(23);
  HiddenModel model(TinyConfig(), true, 6);
  Tensor cover(2, 3, 5, 6);
  cover.data = RandomVector(cover.size(), &rng);
  std::vector<float> message(16);
  for (size_t i = 0; i < message.size(); ++i) message[i] = i % 3 ? 1.f : -1.f;
  Tensor dout(2, 3, 5, 6);
  dout.data = RandomVector(dout.size(), &rng);
  std::vector<Parameter*> params = model.EncoderParameters();
  for (Parameter* p : params) std::fill(p->grad.begin(), p->grad.end(), 0.f);
  model.encoder->Forward(cover, message, false);
  model.encoder->Backward(dout, false);
  auto loss = [&] {
    return Dot(model.encoder->Forward(cover, message, false).data, dout.data);
  };
  ExpectEachParameterGradient(params, loss, &rng);
}

TEST(DecoderTest, FrozenPathGivesImageGradientAndTouchesNoWeights) {
  std::mt19937 rng(24);
  HiddenModel model(TinyConfig(), false, 7);
  std::vector<Parameter*> params = model.DecoderParameters();
  std::vector<std::vector<float>> before;
  for (Parameter* p : params) before.push_back(p->value);
  Decoder decoder(&model);
  ImageRGB image(9, 7);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (float& v : image.data) v = unit(rng);
  const std::vector<float> dlogits = RandomVector(8, &rng);
  const std::vector<float> direction = RandomVector(image.data.size(), &rng);
  ImageRGB grad = decoder.InputGradient(image, dlogits);
  ASSERT_EQ(grad.width, 9);
  ASSERT_EQ(grad.height, 7);
  auto perturb = [&](float t) {
    for (size_t i = 0; i < image.data.size(); ++i)
      image.data[i] += t * direction[i];
  };
  auto loss = [&] { return Dot(decoder.Logits(image), dlogits); };
  const double numeric = Directional(perturb, loss, kStep);
  EXPECT_NEAR(Dot(grad.data, direction), numeric,
              kTolerance * std::abs(numeric) + 1e-5);
  // Weights, running statistics and gradients are untouched.
  for (size_t k = 0; k < params.size(); ++k) {
    EXPECT_EQ(params[k]->value, before[k]) << params[k]->name;
    for (float g : params[k]->grad) ASSERT_EQ(g, 0.f) << params[k]->name;
  }
  // Any image size works (global pooling): 16x16 and 5x3.
  EXPECT_EQ(decoder.Logits(ImageRGB(16, 16)).size(), 8u);
  EXPECT_EQ(decoder.Logits(ImageRGB(5, 3)).size(), 8u);
}

}  // namespace
}  // namespace watergs
