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
  std::vector<float> d(g.size());
  for (size_t i = 0; i < d.size(); ++i)
    d[i] = float(g[i] / g_norm + 0.5 * r[i] / r_norm);
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
  std::vector<std::vector<float>> directions;
  double analytic = 0;
  for (Parameter* p : params) {
    directions.push_back(p->trainable ? RandomVector(p->size(), &rng)
                                      : std::vector<float>(p->size(), 0.f));
    if (p->trainable) analytic += Dot(p->grad, directions.back());
  }
  auto perturb = [&](float t) {
    for (size_t k = 0; k < params.size(); ++k)
      for (size_t i = 0; i < params[k]->size(); ++i)
        params[k]->value[i] += t * directions[k][i];
  };
  auto loss = [&] { return Dot(model.decoder->Forward(image, false).data, w); };
  const double numeric = Directional(perturb, loss, kStep);
  EXPECT_NEAR(analytic, numeric, kTolerance * std::abs(numeric) + 1e-5);
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
  std::vector<std::vector<float>> directions;
  double analytic = 0;
  for (Parameter* p : params) {
    directions.push_back(p->trainable ? RandomVector(p->size(), &rng)
                                      : std::vector<float>(p->size(), 0.f));
    if (p->trainable) analytic += Dot(p->grad, directions.back());
  }
  auto perturb = [&](float t) {
    for (size_t k = 0; k < params.size(); ++k)
      for (size_t i = 0; i < params[k]->size(); ++i)
        params[k]->value[i] += t * directions[k][i];
  };
  auto loss = [&] {
    return Dot(model.encoder->Forward(cover, message, false).data, dout.data);
  };
  const double numeric = Directional(perturb, loss, kStep);
  EXPECT_NE(analytic, 0.0);
  EXPECT_NEAR(analytic, numeric, kTolerance * std::abs(numeric) + 1e-5);
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
