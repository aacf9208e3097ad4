// Random scenes and cameras shared by the rasterizer tests.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"

namespace watergs::testing {

// Options of a random scene.
struct SceneSpec {
  // Number of Gaussians.
  int count = 40;
  // Image size.
  int width = 64, height = 48;
  // Range of world-space standard deviations.
  double min_scale = 0.03, max_scale = 0.2;
  // Range of opacity logits.
  double min_logit = -2.0, max_logit = 2.0;
  // Pixel margin outside the frame where means may fall.
  double margin = 12;
  // Amplitude of the higher SH coefficients.
  double sh_rest_amplitude = 0.3;
  // SH degree of the model.
  int sh_degree = 3;
};

// A camera looking roughly along +z from a pose chosen by `seed`.
inline RenderCamera RandomCamera(int width, int height, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  RenderCamera cam;
  cam.width = width, cam.height = height;
  cam.fx = 0.9 * width + 5 * u(rng);
  cam.fy = cam.fx + 3 * u(rng);
  cam.cx = 0.5 * width + 2 * u(rng);
  cam.cy = 0.5 * height + 2 * u(rng);
  const Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  cam.R = Eigen::AngleAxisd(0.4 * u(rng), axis.normalized()).matrix();
  cam.t = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return cam;
}

// Gaussians whose means project into (or near) the frame at depth 2-6.
inline GaussianModel RandomScene(const RenderCamera& cam, const SceneSpec& spec,
                                 unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> normal(0, 1);
  GaussianModel m;
  m.sh_degree = spec.sh_degree;
  m.Resize(spec.count);
  for (int i = 0; i < spec.count; ++i) {
    const double px = -spec.margin + (cam.width + 2 * spec.margin) * u(rng);
    const double py = -spec.margin + (cam.height + 2 * spec.margin) * u(rng);
    const double z = 2 + 4 * u(rng);
    const Eigen::Vector3d xc((px - cam.cx) / cam.fx * z,
                             (py - cam.cy) / cam.fy * z, z);
    const Eigen::Vector3d xw = cam.R.transpose() * (xc - cam.t);
    for (int k = 0; k < 3; ++k) {
      m.means[3 * i + k] = static_cast<float>(xw[k]);
      const double s =
          spec.min_scale + (spec.max_scale - spec.min_scale) * u(rng);
      m.log_scales[3 * i + k] = static_cast<float>(std::log(s));
      m.sh_dc[3 * i + k] = static_cast<float>(0.2 + 1.5 * u(rng));
    }
    for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = float(normal(rng));
    m.opacity_logits[i] = static_cast<float>(
        spec.min_logit + (spec.max_logit - spec.min_logit) * u(rng));
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[i * m.sh_rest_stride() + k] =
          static_cast<float>(spec.sh_rest_amplitude * (2 * u(rng) - 1));
    }
  }
  return m;
}

}  // namespace watergs::testing
