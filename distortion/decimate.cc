// Decimation by moment-matched merges of nearest neighbours (see
// decimate.h).
#include "distortion/decimate.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "gaussian/point_kdtree.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Log-scales are clamped here before exponentiation: exp(2 * 40) and the sum
// of such covariances stay finite in double, and below -40 a Gaussian is
// flat at any scene scale.
constexpr double kLogScaleClamp = 40.0;

double ClampedLogScale(float s) {
  return std::isnan(s) ? 0.0
                       : std::clamp(double(s), -kLogScaleClamp, kLogScaleClamp);
}

// Covariance R S^2 R^T of Gaussian i.
Eigen::Matrix3d Covariance(const GaussianModel& m, size_t i) {
  const float* q = &m.quats[4 * i];
  Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  if (!(quat.norm() > 0) || !std::isfinite(quat.norm())) {
    quat = Eigen::Quaterniond::Identity();
  }
  const Eigen::Matrix3d r = quat.normalized().toRotationMatrix();
  Eigen::Vector3d var;
  for (int k = 0; k < 3; ++k) {
    var[k] = std::exp(2 * ClampedLogScale(m.log_scales[3 * i + k]));
  }
  return r * var.asDiagonal() * r.transpose();
}

// log(opacity * volume), -Inf for zero opacity.
double LogMass(const GaussianModel& m, size_t i) {
  const double opacity = OpacityLogitToAlpha(m.opacity_logits[i]);
  double log_volume = 0;
  for (int k = 0; k < 3; ++k)
    log_volume += ClampedLogScale(m.log_scales[3 * i + k]);
  return opacity > 0 ? std::log(opacity) + log_volume : -INFINITY;
}

// Share of a in the pair's mass, from the two log-masses (no overflow).
double ShareOfFirst(double log_a, double log_b) {
  if (std::isinf(log_a) && std::isinf(log_b)) return 0.5;
  if (log_a >= log_b) return 1.0 / (1.0 + std::exp(log_b - log_a));
  const double e = std::exp(log_a - log_b);
  return e / (1.0 + e);
}

// Nearest other Gaussian of each (itself if alone), by the means.
std::vector<std::pair<float, uint32_t>> NearestNeighbours(
    const GaussianModel& m) {
  const size_t n = m.size();
  std::vector<std::pair<float, uint32_t>> nearest(n, {INFINITY, 0});
  if (n < 2) return nearest;
  const PointCloudAdaptor cloud{m.means};
  const PointKdTree tree(3, cloud,
                         nanoflann::KDTreeSingleIndexAdaptorParams(10));
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < int64_t(n); ++i) {
    uint32_t index[2];
    float dist2[2];
    const size_t found = tree.knnSearch(&m.means[3 * i], 2, index, dist2);
    // The point itself is one of the two (or a duplicate at distance 0).
    uint32_t other = index[0] == uint32_t(i) ? index[1] : index[0];
    float d = index[0] == uint32_t(i) ? dist2[1] : dist2[0];
    if (found < 2) other = uint32_t(i), d = INFINITY;
    nearest[i] = {d, other};
  }
  return nearest;
}

// One round: merges up to `wanted` disjoint nearest-neighbour pairs,
// closest first. Returns the number merged.
size_t MergeRound(size_t wanted, const GaussianModel& in,
                  const std::vector<uint32_t>& in_source, GaussianModel* out,
                  std::vector<uint32_t>* out_source) {
  const size_t n = in.size();
  const auto nearest = NearestNeighbours(in);
  std::vector<uint32_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return nearest[a].first < nearest[b].first;
  });
  std::vector<bool> used(n, false);
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (uint32_t i : order) {
    if (pairs.size() == wanted) break;
    const uint32_t j = nearest[i].second;
    if (j == i || used[i] || used[j]) continue;
    used[i] = used[j] = true;
    pairs.emplace_back(i, j);
  }
  const size_t kept = n - 2 * pairs.size();
  out_source->clear();
  GaussianModel singles = in;
  std::vector<bool> keep(n);
  for (size_t i = 0; i < n; ++i) keep[i] = !used[i];
  singles.Filter(keep);
  *out = std::move(singles);
  for (size_t i = 0; i < n; ++i) {
    if (!used[i]) out_source->push_back(in_source[i]);
  }
  out->Resize(kept + pairs.size());
  for (size_t p = 0; p < pairs.size(); ++p) {
    const auto [a, b] = pairs[p];
    MergeGaussianPair(in, a, b, out, kept + p);
    const bool a_heavier = ShareOfFirst(LogMass(in, a), LogMass(in, b)) >= 0.5;
    out_source->push_back(in_source[a_heavier ? a : b]);
  }
  return pairs.size();
}

}  // namespace

void MergeGaussianPair(const GaussianModel& in, size_t a, size_t b,
                       GaussianModel* out, size_t into) {
  const double wa = ShareOfFirst(LogMass(in, a), LogMass(in, b));
  const double wb = 1.0 - wa;
  const Eigen::Vector3d ma(in.means[3 * a], in.means[3 * a + 1],
                           in.means[3 * a + 2]);
  const Eigen::Vector3d mb(in.means[3 * b], in.means[3 * b + 1],
                           in.means[3 * b + 2]);
  const Eigen::Vector3d mean = wa * ma + wb * mb;
  const Eigen::Vector3d da = ma - mean, db = mb - mean;
  const Eigen::Matrix3d cov = wa * (Covariance(in, a) + da * da.transpose()) +
                              wb * (Covariance(in, b) + db * db.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(cov);
  Eigen::Matrix3d axes = eigen.eigenvectors();
  Eigen::Vector3d var = eigen.eigenvalues();
  if (eigen.info() != Eigen::Success || !axes.allFinite() || !var.allFinite()) {
    axes.setIdentity();
    var = cov.diagonal();
  }
  if (axes.determinant() < 0) axes.col(0) = -axes.col(0);  // proper rotation
  const Eigen::Quaterniond q(axes);
  for (int k = 0; k < 3; ++k) {
    out->means[3 * into + k] = float(mean[k]);
    // var can be slightly negative from rounding: floor the scale.
    const double log_scale = 0.5 * std::log(std::max(var[k], 0.0));
    out->log_scales[3 * into + k] =
        float(std::clamp(log_scale, double(kLogScaleFloor), kLogScaleClamp));
  }
  const double qv[4] = {q.w(), q.x(), q.y(), q.z()};
  for (int k = 0; k < 4; ++k) out->quats[4 * into + k] = float(qv[k]);
  for (int k = 0; k < 3; ++k) {
    out->sh_dc[3 * into + k] =
        float(wa * in.sh_dc[3 * a + k] + wb * in.sh_dc[3 * b + k]);
  }
  const int stride = in.sh_rest_stride();
  for (int k = 0; k < stride; ++k) {
    out->sh_rest[into * stride + k] = float(wa * in.sh_rest[a * stride + k] +
                                            wb * in.sh_rest[b * stride + k]);
  }
  // 1 - (1 - o_a)(1 - o_b): the pair's coverage where both overlap.
  const double oa = OpacityLogitToAlpha(in.opacity_logits[a]);
  const double ob = OpacityLogitToAlpha(in.opacity_logits[b]);
  out->opacity_logits[into] =
      AlphaToOpacityLogit(1.0 - (1.0 - oa) * (1.0 - ob));
}

void Decimate(double fraction, const GaussianModel& in, GaussianModel* out,
              std::vector<uint32_t>* source) {
  if (!(fraction >= 0 && fraction < 1)) {
    Fail("decimate: the fraction must be in [0, 1), not " +
         std::to_string(fraction));
  }
  const size_t n = in.size();
  const size_t target = n - size_t(std::floor(fraction * double(n)));
  GaussianModel current = in;
  std::vector<uint32_t> current_source(n);
  for (size_t i = 0; i < n; ++i) current_source[i] = uint32_t(i);
  while (current.size() > target) {
    GaussianModel next;
    std::vector<uint32_t> next_source;
    const size_t merged = MergeRound(current.size() - target, current,
                                     current_source, &next, &next_source);
    if (merged == 0) break;  // a single Gaussian is left
    current = std::move(next);
    current_source = std::move(next_source);
  }
  *out = std::move(current);
  *source = std::move(current_source);
}

}  // namespace watergs
