// Test helper shared by the embedding tests (embedder_test.cc,
// embedder_device_protocol_test.cc): a tiny scene of a random ball seen by
// a ring of views whose ground truth is the ball's own render, and a tiny
// decoder configuration.
#pragma once

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
#include "watermark/hidden_net.h"

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

}  // namespace watergs::testing
