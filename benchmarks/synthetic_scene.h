// Synthetic SfM-like scenes and cameras shared by the benchmarks
// (raster_benchmark, embed_benchmark): the same scene generator gives the
// same scenes, so figures of different benchmarks are comparable.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

// 480x360 (scale 1) or 1920x1080-like views of the same scene (scale 4).
inline RenderCamera BenchCamera(int scale = 1) {
  RenderCamera cam;
  cam.width = 480 * scale, cam.height = scale == 1 ? 360 : 270 * scale;
  cam.fx = cam.fy = 420 * scale;
  cam.cx = 0.5 * cam.width, cam.cy = 0.5 * cam.height;
  cam.R =
      Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.3, 1, 0).normalized()).matrix();
  cam.t = Eigen::Vector3d(0.1, -0.05, 0.2);
  return cam;
}

// Mean distance to the 3 nearest neighbours, via a uniform grid.
inline std::vector<double> ThreeNnDistance(
    const std::vector<Eigen::Vector3d>& pts, double cell) {
  auto key = [&](const Eigen::Vector3d& p, int dx, int dy, int dz) {
    const long long x = std::llround(std::floor(p.x() / cell)) + dx;
    const long long y = std::llround(std::floor(p.y() / cell)) + dy;
    const long long z = std::llround(std::floor(p.z() / cell)) + dz;
    return (x * 73856093LL) ^ (y * 19349663LL) ^ (z * 83492791LL);
  };
  std::unordered_multimap<long long, int> grid;
  for (size_t i = 0; i < pts.size(); ++i) grid.emplace(key(pts[i], 0, 0, 0), i);
  std::vector<double> out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    double best[3] = {1e30, 1e30, 1e30};
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          auto range = grid.equal_range(key(pts[i], dx, dy, dz));
          for (auto it = range.first; it != range.second; ++it) {
            if (it->second == static_cast<int>(i)) continue;
            const double d2 = (pts[it->second] - pts[i]).squaredNorm();
            if (d2 < best[2]) {
              best[2] = d2;
              std::sort(best, best + 3);
            }
          }
        }
      }
    }
    out[i] = std::sqrt((std::min(best[0], cell * cell) +
                        std::min(best[1], cell * cell) +
                        std::min(best[2], cell * cell)) /
                       3);
  }
  return out;
}

// Like an SfM initialisation: points on surfaces seen by the view and around
// it (a wavy backdrop at depth ~6 spanning 1.4 x the frustum, plus a few
// spherical objects at depth 2-4), isotropic scales from the 3-NN spacing
// (Inria's init), opacity 0.1; `trained` adds anisotropy and spread-out
// opacities.
inline GaussianModel SyntheticScene(const RenderCamera& cam, size_t n,
                                    int sh_degree, bool trained,
                                    unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Eigen::Vector3d> pts(n);
  const Eigen::Vector3d objects[4] = {
      {-0.8, 0.3, 3.0}, {0.6, -0.2, 2.5}, {0.1, 0.5, 4.0}, {1.2, 0.6, 3.5}};
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d p;
    if (i % 4 != 0) {
      const double sx = (u(rng) - 0.5) * 1.4 * cam.width / cam.fx;
      const double sy = (u(rng) - 0.5) * 1.4 * cam.height / cam.fy;
      const double z = 6 + 1.5 * std::sin(4 * sx) * std::cos(3 * sy);
      p = Eigen::Vector3d(sx * z, sy * z, z);
    } else {
      const Eigen::Vector3d dir(normal(rng), normal(rng), normal(rng));
      p = objects[i % 16 / 4] + 0.5 * dir.normalized();
    }
    pts[i] = cam.R.transpose() * (p - cam.t);
  }
  // Grid cells of ~2.5 x the expected spacing on the ~125 m^2 of surface.
  const double cell = 2.5 * std::sqrt(125.0 / n);
  const std::vector<double> spacing = ThreeNnDistance(pts, cell);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      m.means[3 * i + k] = static_cast<float>(pts[i][k]);
      const double aniso = trained ? std::exp(0.5 * normal(rng)) : 1.0;
      m.log_scales[3 * i + k] =
          static_cast<float>(std::log(spacing[i] * aniso));
      m.sh_dc[3 * i + k] = static_cast<float>(normal(rng));
    }
    for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = float(normal(rng));
    m.opacity_logits[i] = trained ? float(normal(rng)) : -2.1972246f;
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[i * m.sh_rest_stride() + k] = float(0.1 * normal(rng));
    }
  }
  return m;
}

}  // namespace watergs
