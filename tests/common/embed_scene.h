// Test helper shared by the embedding tests (embedder_test.cc,
// embedder_device_protocol_test.cc, concat_encoder_test.cc): a tiny scene of a
// random ball seen by a ring of views whose ground truth is the ball's own
// render, a tiny decoder configuration made responsive, and random messages.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/trainer.h"
#include "tests/common/look_at.h"
#include "watermark/decoder.h"
#include "watermark/hidden_net.h"
#include "watermark/message.h"

namespace watergs::testing {

inline GaussianModel RandomBall(int n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianModel m;
  m.sh_degree = 1;
  m.Resize(n);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      m.means[3 * i + a] = 0.8f * u(rng);
      m.log_scales[3 * i + a] = std::log(scale * (1.2f + 0.5f * u(rng)));
      m.sh_dc[3 * i + a] = 1.2f * u(rng);
    }
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[m.sh_rest_stride() * i + k] = 0.1f * u(rng);
    }
    m.quats[4 * i] = 1;
    m.quats[4 * i + 1] = 0.3f * u(rng);
    m.opacity_logits[i] = 1.0f + u(rng);
  }
  return m;
}

// A scene rendered from its own model (the raw model is already converged).
struct Scene {
  InMemoryViews views;
  std::vector<size_t> train;
  GaussianModel model;
};

inline Scene MakeScene(int num_views, int w, int h) {
  Scene s;
  s.model = RandomBall(80, 1, 0.12f);
  auto rasterizer = MakeCpuRasterizer();
  for (int v = 0; v < num_views; ++v) {
    const double a = 2 * M_PI * v / num_views;
    const RenderCamera cam = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), w, h);
    ImageRGB image;
    rasterizer->Forward(s.model, cam, RenderOptions{}, &image, nullptr);
    s.views.Add("view" + std::to_string(v), cam, image);
    s.train.push_back(v);
  }
  return s;
}

inline HiddenConfig TinyDecoderConfig(int bits) {
  HiddenConfig config;
  config.num_bits = bits;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 2;
  return config;
}

// Moves the scene's photos off its own renders by 0.02 to 0.03 per value,
// so that every pixel's image-loss gradient has a sign the data fixes. On
// its own renders the CPU's image loss is flat bit for bit (render ==
// photo: L1's sign and the SSIM terms are exactly 0 there) while another
// backend's render differs from the photo by rounding, which L1's sign and
// Adam's normalised first steps turn into full-size steps of arbitrary sign
// for every Gaussian outside the decoded crop: a cross-backend comparison
// on such photos compares rounding noise (issue 26; see
// EmbedderDeviceProtocol.RoundingOnTheScenesOwnRendersDiverges).
inline void OffsetPhotos(Scene* s) {
  InMemoryViews views;
  for (size_t v = 0; v < s->views.NumViews(); ++v) {
    ImageRGB image = *s->views.Image(v);
    for (size_t k = 0; k < image.data.size(); ++k) {
      image.data[k] += 0.02f + 0.01f * float(k % 7) / 6.f;
    }
    views.Add(s->views.Name(v), s->views.Camera(v), std::move(image));
  }
  s->views = std::move(views);
}

// A freshly initialised decoder reads nearly the same logits from every
// image (its pooled features barely vary), unlike a trained one. Scaling the
// final linear layer by `gain` and centring its bias on the scene's renders
// gives the random decoder a trained one's sensitivity.
inline void MakeResponsive(HiddenModel* net, float gain,
                           const TrainingViews& views) {
  Parameter *weight = nullptr, *bias = nullptr;
  for (Parameter* p : net->DecoderParameters()) {
    if (p->name == "decoder.linear.weight") weight = p;
    if (p->name == "decoder.linear.bias") bias = p;
  }
  ASSERT_TRUE(weight && bias);
  for (float& w : weight->value) w *= gain;
  for (float& b : bias->value) b *= gain;
  Decoder decoder(net);
  std::vector<double> mean(bias->value.size(), 0);
  for (size_t v = 0; v < views.NumViews(); ++v) {
    const std::vector<float> logits = decoder.Logits(*views.Image(v));
    for (size_t i = 0; i < mean.size(); ++i) {
      mean[i] += logits[i] / views.NumViews();
    }
  }
  for (size_t i = 0; i < mean.size(); ++i) bias->value[i] -= mean[i];
}

inline Bits RandomBits(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  Bits bits(n);
  for (auto& b : bits) b = rng() & 1;
  return bits;
}

}  // namespace watergs::testing
