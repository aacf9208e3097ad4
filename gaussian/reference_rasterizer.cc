// Reference rasterizer: one Gaussian at a time, one pixel at a time, in
// double. Deliberately shares no projection or blending code with the fast
// path (only the SH basis, whose constants sh_test checks on its own, and
// the viewers' storage rules of render_conventions.h: StoredBaseColor,
// StoredOpacity, CompactSplat, CompactColor, whose levels
// render_conventions_test checks by hand).
#include "gaussian/reference_rasterizer.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include "gaussian/sh.h"

namespace watergs {
namespace {

// One Gaussian as the reference sees it after projection.
struct RefSplat {
  bool valid = false;
  Eigen::Vector2d mean;
  Eigen::Matrix2d conic;
  double depth = 0, opacity = 0;
  Eigen::Vector3d color;
  // Inria's tile rectangle [x0, x1) x [y0, y1) in tiles.
  int tx0 = 0, ty0 = 0, tx1 = 0, ty1 = 0;
  Falloff falloff = Falloff::kInria;
};

RefSplat ProjectRef(const ReferenceModel& m, size_t i, const RenderCamera& cam,
                    int degree, const RenderConventions& conventions) {
  RefSplat s;
  const Eigen::Vector3d world(m.means[3 * i], m.means[3 * i + 1],
                              m.means[3 * i + 2]);
  const Eigen::Vector3d t = cam.R * world + cam.t;
  if (!(t.z() >= cam.near_plane && t.z() <= cam.far_plane)) return s;
  double quat[4] = {m.quats[4 * i], m.quats[4 * i + 1], m.quats[4 * i + 2],
                    m.quats[4 * i + 3]};
  double log_scale[3] = {m.log_scales[3 * i], m.log_scales[3 * i + 1],
                         m.log_scales[3 * i + 2]};
  double opacity = 1.0 / (1.0 + std::exp(-m.opacity_logits[i]));
  if (conventions.compact_work_buffer) {
    CompactSplat(log_scale, quat, &opacity);
  }
  Eigen::Quaterniond q(quat[0], quat[1], quat[2], quat[3]);
  const Eigen::Matrix3d rot = q.squaredNorm() > 1e-24
                                  ? q.normalized().toRotationMatrix()
                                  : Eigen::Matrix3d::Identity();
  Eigen::Vector3d scale;
  for (int k = 0; k < 3; ++k) {
    scale[k] = std::exp(std::clamp(log_scale[k], -30.0, 20.0));
  }
  const Eigen::Matrix3d sigma =
      rot * scale.asDiagonal() * scale.asDiagonal() * rot.transpose();
  const double no_clamp = std::numeric_limits<double>::infinity();
  const double limx = conventions.unclamped_jacobian
                          ? no_clamp
                          : 1.3 * 0.5 * cam.width / cam.fx;
  const double limy = conventions.unclamped_jacobian
                          ? no_clamp
                          : 1.3 * 0.5 * cam.height / cam.fy;
  const double xz = std::clamp(t.x() / t.z(), -limx, limx);
  const double yz = std::clamp(t.y() / t.z(), -limy, limy);
  Eigen::Matrix<double, 2, 3> J;
  J << cam.fx / t.z(), 0, -cam.fx * xz / t.z(), 0, cam.fy / t.z(),
      -cam.fy * yz / t.z();
  const Eigen::Matrix<double, 2, 3> JW = J * cam.R;
  const Eigen::Matrix2d cov =
      JW * sigma * JW.transpose() + 0.3 * Eigen::Matrix2d::Identity();
  if (!(cov.determinant() > 0)) return s;
  s.conic = cov.inverse();
  s.mean = Eigen::Vector2d(cam.fx * t.x() / t.z() + cam.cx,
                           cam.fy * t.y() / t.z() + cam.cy);
  const double cull = conventions.cull_centre_outside;
  if (cull > 0 && !(std::abs(2 * s.mean.x() / cam.width - 1) <= cull &&
                    std::abs(2 * s.mean.y() / cam.height - 1) <= cull)) {
    return s;
  }
  // Another renderer's dilation and extent cap change the blended ellipse,
  // not the tiles (those of Inria's ellipse, a superset).
  Eigen::Matrix2d blended = cov;
  if (conventions.dilation_px2 >= 0) {
    blended -= (0.3 - conventions.dilation_px2) * Eigen::Matrix2d::Identity();
    if (!(blended.determinant() > 0)) return s;
  }
  if (conventions.min_extent_px > 0) {
    const double lambda1 =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(blended).eigenvalues()(
            1);
    if (!(2 * std::sqrt(2 * lambda1) >= conventions.min_extent_px)) return s;
  }
  if (conventions.extent_cap_px > 0) {
    const double cap = std::min({double(conventions.extent_cap_px),
                                 double(cam.width), double(cam.height)});
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(blended);
    const Eigen::Vector2d capped = eigen.eigenvalues().cwiseMin(cap * cap / 8);
    blended = eigen.eigenvectors() * capped.asDiagonal() *
              eigen.eigenvectors().transpose();
  }
  if (conventions.eigen_gap_floor > 0) {
    const double a = blended(0, 0), b = blended(0, 1), d = blended(1, 1);
    const double disc = 0.25 * (a - d) * (a - d) + b * b;
    const double half_gap =
        std::sqrt(std::max(conventions.eigen_gap_floor, disc));
    const double l1 = 0.5 * (a + d) + half_gap, l2 = 0.5 * (a + d) - half_gap;
    if (!(l2 > 0)) return s;
    Eigen::Vector2d major(b, l1 - a);
    major = major.norm() > 0 ? major.normalized() : Eigen::Vector2d(1, 0);
    const Eigen::Vector2d minor(major.y(), -major.x());
    blended = l1 * major * major.transpose() + l2 * minor * minor.transpose();
  }
  s.conic = blended.inverse();
  if (!m.screen_offsets.empty()) {
    s.mean +=
        Eigen::Vector2d(m.screen_offsets[2 * i], m.screen_offsets[2 * i + 1]);
  }
  const double mid = 0.5 * cov.trace();
  const double lambda =
      mid + std::sqrt(std::max(0.1, mid * mid - cov.determinant()));
  const double radius = std::min(1e6, std::ceil(3 * std::sqrt(lambda)));
  const int grid_x = (cam.width + 15) / 16, grid_y = (cam.height + 15) / 16;
  auto tile = [](double v, int grid) {
    return static_cast<int>(std::clamp(v, 0.0, double(grid)));
  };
  const double px = s.mean.x() - 0.5, py = s.mean.y() - 0.5;
  s.tx0 = tile((px - radius) / 16, grid_x);
  s.tx1 = tile((px + radius + 15) / 16, grid_x);
  s.ty0 = tile((py - radius) / 16, grid_y);
  s.ty1 = tile((py + radius + 15) / 16, grid_y);
  s.depth = t.z();
  s.falloff = conventions.falloff;
  s.opacity = StoredOpacity(opacity, conventions);
  const double dir[3] = {world.x() - cam.Center().x(),
                         world.y() - cam.Center().y(),
                         world.z() - cam.Center().z()};
  double rgb[3];
  ShColorUnclamped(degree, &m.sh_dc[3 * i],
                   m.sh_rest.data() + i * m.sh_rest_stride(), dir, rgb);
  for (int ch = 0; ch < 3; ++ch) {
    const double base = kShC0 * m.sh_dc[3 * i + ch] + 0.5;
    rgb[ch] += StoredBaseColor(base, conventions) - base;
    if (conventions.compact_work_buffer) rgb[ch] = CompactColor(rgb[ch], ch);
  }
  s.color = Eigen::Vector3d(std::max(rgb[0], 0.0), std::max(rgb[1], 0.0),
                            std::max(rgb[2], 0.0));
  s.valid = true;
  return s;
}

double AlphaAt(const RefSplat& s, double x, double y, double* power) {
  const Eigen::Vector2d d = Eigen::Vector2d(x + 0.5, y + 0.5) - s.mean;
  *power = -0.5 * d.dot(s.conic * d);
  double falloff = std::exp(*power);
  if (s.falloff != Falloff::kInria && *power < -4) falloff = 0;
  if (s.falloff == Falloff::kNormalized && falloff > 0) {
    falloff = (falloff - std::exp(-4.0)) / (1 - std::exp(-4.0));
  }
  return std::min(0.99, s.opacity * falloff);
}

// Inria's sum: colour * alpha * T front to back, the background times the
// transmittance left.
Eigen::Vector3d CompositeFrontToBack(
    const std::vector<RefSplat>& splats,
    const std::vector<std::pair<uint32_t, double>>& blended,
    const Eigen::Vector3d& background) {
  Eigen::Vector3d color = Eigen::Vector3d::Zero();
  double T = 1;
  for (const auto& [id, alpha] : blended) {
    color += splats[id].color * alpha * T;
    T *= 1 - alpha;
  }
  return color + T * background;
}

// A WebGL RGBA8 canvas' premultiplied blend, back to front: the background
// stored in 8 bits, then dst = unorm8(min(1, colour * alpha) + dst (1 -
// alpha)) per splat, unorm8(v) = floor(255 clamp(v, 0, 1) + 0.5) / 255.
Eigen::Vector3d CompositeBackToFront8(
    const std::vector<RefSplat>& splats,
    const std::vector<std::pair<uint32_t, double>>& blended,
    const Eigen::Vector3d& background) {
  auto unorm8 = [](double v) {
    return std::floor(std::clamp(v, 0.0, 1.0) * 255 + 0.5) / 255;
  };
  Eigen::Vector3d dst = background.unaryExpr(unorm8);
  for (auto it = blended.rbegin(); it != blended.rend(); ++it) {
    const auto& [id, alpha] = *it;
    for (int ch = 0; ch < 3; ++ch) {
      const double src = std::min(1.0, splats[id].color[ch] * alpha);
      dst[ch] = unorm8(src + dst[ch] * (1 - alpha));
    }
  }
  return dst;
}

}  // namespace

ReferenceModel ReferenceModel::From(const GaussianModel& model) {
  ReferenceModel r;
  r.sh_degree = model.sh_degree;
  auto copy = [](const std::vector<float>& v) {
    return std::vector<double>(v.begin(), v.end());
  };
  r.means = copy(model.means), r.log_scales = copy(model.log_scales);
  r.quats = copy(model.quats), r.opacity_logits = copy(model.opacity_logits);
  r.sh_dc = copy(model.sh_dc), r.sh_rest = copy(model.sh_rest);
  return r;
}

std::vector<double> ReferenceRender(const ReferenceModel& model,
                                    const RenderCamera& camera,
                                    const RenderOptions& options,
                                    const ReferenceDecisions* replay,
                                    ReferenceDecisions* record) {
  PixelRect rect = options.rect;
  if (rect.empty()) rect = {0, 0, camera.width, camera.height};
  const int degree = EffectiveShDegree(options.active_sh_degree,
                                       model.sh_degree, options.conventions);
  std::vector<RefSplat> splats(model.size());
  for (size_t i = 0; i < model.size(); ++i) {
    splats[i] = ProjectRef(model, i, camera, degree, options.conventions);
  }
  std::vector<uint32_t> order(model.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return splats[a].depth < splats[b].depth;
  });
  std::vector<double> image(size_t(rect.width) * rect.height * 3);
  if (record) record->contributors.assign(size_t(rect.width) * rect.height, {});
  for (int y = rect.y0; y < rect.y0 + rect.height; ++y) {
    for (int x = rect.x0; x < rect.x0 + rect.width; ++x) {
      const size_t p = size_t(y - rect.y0) * rect.width + (x - rect.x0);
      // The pixel's contributions front to back: (splat, alpha).
      std::vector<std::pair<uint32_t, double>> blended;
      double T = 1;
      if (replay) {
        for (uint32_t id : replay->contributors[p]) {
          double power;
          const double alpha = AlphaAt(splats[id], x, y, &power);
          blended.emplace_back(id, alpha);
          T *= 1 - alpha;
        }
      } else {
        for (uint32_t id : order) {
          const RefSplat& s = splats[id];
          const bool in_tile = s.valid && x / 16 >= s.tx0 && x / 16 < s.tx1 &&
                               y / 16 >= s.ty0 && y / 16 < s.ty1;
          if (!in_tile) continue;
          double power;
          const double alpha = AlphaAt(s, x, y, &power);
          if (power > 0 || alpha < 1.0 / 255.0) continue;
          if (T * (1 - alpha) < 1e-4) break;
          blended.emplace_back(id, alpha);
          T *= 1 - alpha;
          if (record) record->contributors[p].push_back(id);
        }
      }
      const Eigen::Vector3d background(
          options.background[0], options.background[1], options.background[2]);
      const Eigen::Vector3d color =
          options.conventions.composite_8bit
              ? CompositeBackToFront8(splats, blended, background)
              : CompositeFrontToBack(splats, blended, background);
      for (int ch = 0; ch < 3; ++ch) image[3 * p + ch] = color[ch];
    }
  }
  return image;
}

}  // namespace watergs
