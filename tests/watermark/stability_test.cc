// Numerical stability of the watermark pieces: BCE with saturated and
// infinite logits, the decoder on constant and black images, embedding with
// gamma 0, with all-zero and all-one messages, and with an empty mask.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "gaussian/util/error.h"
#include "tests/common/look_at.h"
#include "watermark/embedder.h"
#include "watermark/hidden_model.h"
#include "watermark/nn_layers.h"

namespace watergs {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(Stability, BceWithSaturatedLogitsIsExactAndFinite) {
  // |z| = 1e4: a right bit costs exp(-1e4) = 0, a wrong one |z| exactly.
  Tensor logits(1, 4, 1, 1);
  logits.data = {1e4f, -1e4f, 1e4f, -1e4f};
  Tensor grad;
  const double value = BceWithLogits(logits, {1, 0, 0, 1}, &grad);
  EXPECT_DOUBLE_EQ(value, 2e4 / 4);
  EXPECT_EQ(grad.data[0], 0.f);
  EXPECT_EQ(grad.data[1], 0.f);
  EXPECT_FLOAT_EQ(grad.data[2], 0.25f);
  EXPECT_FLOAT_EQ(grad.data[3], -0.25f);
}

TEST(Stability, BceWithInfiniteLogitsNeverGivesNaN) {
  // A right bit at an infinite logit costs 0 (not inf - inf), a wrong one
  // +inf (the embedder reports a non-finite loss); the gradient stays the
  // bounded sigmoid(z) - t.
  Tensor logits(1, 2, 1, 1);
  logits.data = {kInf, -kInf};
  Tensor grad;
  EXPECT_EQ(BceWithLogits(logits, {1, 0}, &grad), 0.0);
  EXPECT_EQ(grad.data[0], 0.f);
  EXPECT_EQ(grad.data[1], 0.f);
  EXPECT_EQ(BceWithLogits(logits, {0, 1}, &grad), double(kInf));
  EXPECT_FLOAT_EQ(grad.data[0], 0.5f);
  EXPECT_FLOAT_EQ(grad.data[1], -0.5f);
  // Soft targets with a finite logit keep the usual value.
  logits.data = {2.f, -3.f};
  const double soft = BceWithLogits(logits, {0.25f, 0.5f}, &grad);
  const double expected = (std::log1p(std::exp(2.0)) - 2.0 * 0.25 +
                           std::log1p(std::exp(-3.0)) + 3.0 * 0.5) /
                          2;
  EXPECT_NEAR(soft, expected, 1e-12);
}

HiddenConfig TinyConfig(int bits) {
  HiddenConfig config;
  config.num_bits = bits;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 2;
  return config;
}

TEST(Stability, DecoderOnConstantImagesGivesFiniteLogitsAndGradients) {
  HiddenModel net(TinyConfig(8), false, 7);
  Decoder decoder(&net);
  const std::vector<float> dlogits = {1, -1, 0.5, -0.5, 2, -2, 1e3, -1e3};
  for (int size : {1, 2, 17}) {
    for (float value : {0.f, 1.f, 0.5f}) {
      ImageRGB image(size, size);
      std::fill(image.data.begin(), image.data.end(), value);
      const std::vector<float> logits = decoder.Logits(image);
      ASSERT_EQ(logits.size(), 8u);
      for (float z : logits) EXPECT_TRUE(std::isfinite(z)) << value;
      const ImageRGB grad = decoder.InputGradient(image, dlogits);
      ASSERT_EQ(grad.data.size(), image.data.size());
      double norm = 0;
      for (float g : grad.data) {
        ASSERT_TRUE(std::isfinite(g)) << size << " " << value;
        norm += double(g) * g;
      }
      // A constant image does not switch the gradient off.
      EXPECT_GT(norm, 0) << size << " " << value;
    }
  }
}

GaussianModel RandomBall(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianModel m;
  m.sh_degree = 1;
  m.Resize(n);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      m.means[3 * i + a] = 0.8f * u(rng);
      m.log_scales[3 * i + a] = std::log(0.12f * (1.2f + 0.5f * u(rng)));
      m.sh_dc[3 * i + a] = 1.2f * u(rng);
    }
    m.quats[4 * i] = 1;
    m.opacity_logits[i] = 1.0f + u(rng);
  }
  return m;
}

struct Scene {
  InMemoryViews views;
  std::vector<size_t> train;
  GaussianModel model;
};
Scene MakeScene() {
  Scene s;
  s.model = RandomBall(50, 1);
  auto rasterizer = MakeCpuRasterizer();
  for (int v = 0; v < 2; ++v) {
    const double a = M_PI * v;
    const RenderCamera camera = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 24, 20);
    ImageRGB image;
    rasterizer->Forward(s.model, camera, RenderOptions{}, &image, nullptr);
    s.views.Add("view" + std::to_string(v), camera, image);
    s.train.push_back(v);
  }
  return s;
}

EmbedOptions SmallEmbed(int64_t iterations) {
  EmbedOptions o = DefaultEmbedOptions(iterations);
  o.crop_size = 16;
  o.densify = false;
  o.distortions = ParseDistortionList("identity,gn:0.01");
  return o;
}

TEST(Stability, GammaZeroEmbeddingIgnoresTheMessage) {
  // With gamma 0 the message term is switched off: two different messages
  // give bit-identical models, and nothing non-finite appears.
  Scene s = MakeScene();
  HiddenModel net(TinyConfig(8), false, 3);
  Decoder decoder(&net);
  EmbedOptions o = SmallEmbed(6);
  o.gamma = 0;
  Embedder a(o, s.views, s.train, s.model, 3.0, &decoder,
             ParseMessage("bits:00000000", 8), MakeCpuRasterizer());
  Embedder b(o, s.views, s.train, s.model, 3.0, &decoder,
             ParseMessage("bits:11111111", 8), MakeCpuRasterizer());
  for (int i = 0; i < 6; ++i) {
    const EmbedStepStats sa = a.Step(), sb = b.Step();
    EXPECT_TRUE(std::isfinite(sa.total));
    EXPECT_EQ(sa.total, sa.image.total);
  }
  EXPECT_EQ(a.model().means, b.model().means);
  EXPECT_EQ(a.model().sh_dc, b.model().sh_dc);
  EXPECT_EQ(a.model().CountNonFinite(), 0u);
}

TEST(Stability, AllZeroAndAllOneMessagesEmbedFinitely) {
  Scene s = MakeScene();
  HiddenModel net(TinyConfig(16), false, 4);
  Decoder decoder(&net);
  // Both runs decode the same render in their first iteration (same model,
  // same seed: the message draws nothing), and each logit reads 0 or 1, so
  // every bit is wrong for exactly one of the two messages.
  int first_errors = 0;
  for (const char* text : {"bits:0000000000000000", "hex:ffff"}) {
    const Bits message = ParseMessage(text, 16);
    const bool ones = text[0] == 'h';
    for (uint8_t bit : message) ASSERT_EQ(bit, ones ? 1 : 0) << text;
    Embedder embedder(SmallEmbed(4), s.views, s.train, s.model, 3.0, &decoder,
                      message, MakeCpuRasterizer());
    for (int i = 0; i < 4; ++i) {
      const EmbedStepStats stats = embedder.Step();
      EXPECT_TRUE(std::isfinite(stats.bce)) << text;
      if (i == 0) first_errors += stats.bit_errors;
    }
    EXPECT_EQ(embedder.model().CountNonFinite(), 0u) << text;
    const CheckResult check = embedder.Check(s.train);
    EXPECT_TRUE(std::isfinite(check.mean_ber) && std::isfinite(check.psnr));
  }
  EXPECT_EQ(first_errors, 16);
}

TEST(Stability, EmptyMaskIsRefused) {
  // Nothing trainable would run the whole fine-tuning for no change: refused
  // up front with one line (the CLI's --mask parser refuses "" too).
  Scene s = MakeScene();
  HiddenModel net(TinyConfig(8), false, 3);
  Decoder decoder(&net);
  EmbedOptions o = SmallEmbed(2);
  o.trainable.fill(false);
  try {
    Embedder embedder(o, s.views, s.train, s.model, 3.0, &decoder,
                      ParseMessage("hex:a5", 8), MakeCpuRasterizer());
    ADD_FAILURE() << "an empty mask was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no trainable parameter group"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(ParseParamMask(""), Error);
  EXPECT_THROW(ParseParamMask(","), Error);
}

}  // namespace
}  // namespace watergs
