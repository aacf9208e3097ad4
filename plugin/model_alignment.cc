// Checking a model against its workspace's photos, and finding the frame it
// was saved in.
#include "plugin/model_alignment.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <random>

#include "gaussian/loss.h"
#include "gaussian/point_kdtree.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/photometric_refinement.h"
#include "plugin/workspace.h"

namespace watergs {
namespace {

using Eigen::Matrix3d;
using Eigen::Matrix3Xd;
using Eigen::Vector3d;

// Points ICP works on: enough for a robust fit, few enough for seconds.
constexpr size_t kSearchPoints = 4000;
// Points each of the many starts is refined on.
constexpr size_t kCoarsePoints = 1000;
// ICP placements below this correlation are not refined photometrically.
constexpr double kRefineAboveCorrelation = 0.6;
// Width of the renders the photometric refinement fits.
constexpr double kRefineWidth = 320;
// Neighbours a normal is fitted to.
constexpr size_t kNormalNeighbours = 10;
// Rotations spread at random over all, besides the principal axes' 48.
constexpr int kSpreadStarts = 72;
// Share of the nearest-neighbour pairs ICP keeps in each direction: the
// clouds differ (floaters, background the SfM points never reached).
constexpr double kTrim = 0.7;
// Gaussians this transparent are left out of the model's cloud.
constexpr float kMinAlpha = 0.3f;

// Every `stride`-th point so that at most `max_points` remain, as 3 x N.
Matrix3Xd Subsample(const std::vector<float>& xyz, size_t max_points) {
  const size_t n = xyz.size() / 3;
  const size_t stride = std::max<size_t>(1, (n + max_points - 1) / max_points);
  Matrix3Xd out(3, (n + stride - 1) / stride);
  for (size_t i = 0, k = 0; i < n; i += stride, ++k) {
    out.col(k) = Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  }
  return out;
}

std::vector<float> ToFloats(const Matrix3Xd& points) {
  std::vector<float> xyz(points.size());
  for (Eigen::Index k = 0; k < points.cols(); ++k) {
    for (int d = 0; d < 3; ++d) xyz[3 * k + d] = float(points(d, k));
  }
  return xyz;
}

double Quantile(std::vector<double> values, double q) {
  const size_t k = std::min(values.size() - 1, size_t(q * values.size()));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

// A cloud's robust centre, principal axes (columns, a proper rotation) and
// spread (median distance from the centre).
struct Frame {
  Vector3d centre;
  Matrix3d axes;
  double spread = 0;
};

Frame PrincipalFrame(const Matrix3Xd& points) {
  Frame f;
  for (int d = 0; d < 3; ++d) {
    std::vector<double> values(points.cols());
    for (Eigen::Index k = 0; k < points.cols(); ++k) values[k] = points(d, k);
    f.centre[d] = Quantile(values, 0.5);
  }
  std::vector<double> distance(points.cols());
  for (Eigen::Index k = 0; k < points.cols(); ++k) {
    distance[k] = (points.col(k) - f.centre).norm();
  }
  f.spread = Quantile(distance, 0.5);
  // Axes from the inner 90%: far floaters would otherwise set them.
  const double reach = Quantile(distance, 0.9);
  Matrix3d covariance = Matrix3d::Zero();
  for (Eigen::Index k = 0; k < points.cols(); ++k) {
    if (distance[k] > reach) continue;
    const Vector3d d = points.col(k) - f.centre;
    covariance += d * d.transpose();
  }
  f.axes = Eigen::SelfAdjointEigenSolver<Matrix3d>(covariance).eigenvectors();
  if (f.axes.determinant() < 0) f.axes.col(0) *= -1;
  return f;
}

// The 24 rotations that map the axes onto signed axes.
std::vector<Matrix3d> AxisRotations() {
  std::vector<Matrix3d> out;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                           {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms) {
    for (int signs = 0; signs < 8; ++signs) {
      Matrix3d m = Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) m(r, p[r]) = (signs >> r & 1) ? -1 : 1;
      if (m.determinant() > 0) out.push_back(m);
    }
  }
  return out;
}

Vector3d Apply(const SimilarityTransform& t, const Vector3d& x) {
  return t.scale * t.rotation * x + t.translation;
}

// Nearest neighbours of `queries` in `cloud`: for each kept pair (the
// closest kTrim), the query's column and the neighbour's column.
struct Pairs {
  std::vector<Eigen::Index> query, neighbour;
  std::vector<double> distance;  // every query's, kept or not
};

Pairs NearestPairs(const Matrix3Xd& queries, const Matrix3Xd& cloud) {
  const std::vector<float> xyz = ToFloats(cloud);
  const PointCloudAdaptor adaptor{xyz};
  const PointKdTree tree(3, adaptor,
                         nanoflann::KDTreeSingleIndexAdaptorParams(10));
  Pairs pairs;
  std::vector<uint32_t> nearest(queries.cols());
  pairs.distance.resize(queries.cols());
  for (Eigen::Index k = 0; k < queries.cols(); ++k) {
    const float q[3] = {float(queries(0, k)), float(queries(1, k)),
                        float(queries(2, k))};
    float d2 = 0;
    tree.knnSearch(q, 1, &nearest[k], &d2);
    pairs.distance[k] = std::sqrt(double(d2));
  }
  const double cut = Quantile(pairs.distance, kTrim);
  for (Eigen::Index k = 0; k < queries.cols(); ++k) {
    if (pairs.distance[k] > cut) continue;
    pairs.query.push_back(k);
    pairs.neighbour.push_back(nearest[k]);
  }
  return pairs;
}

// One round of ICP: the source moved by `transform`, its nearest pairs in
// both directions, and their median distance as a fraction of `spread`.
struct IcpRound {
  Matrix3Xd moved;
  Pairs forward, backward;
  double residual = 0;
};

IcpRound MatchBothWays(const SimilarityTransform& transform,
                       const Matrix3Xd& source, const Matrix3Xd& target,
                       double spread) {
  IcpRound round;
  round.moved.resize(3, source.cols());
  for (Eigen::Index k = 0; k < source.cols(); ++k) {
    round.moved.col(k) = Apply(transform, source.col(k));
  }
  round.forward = NearestPairs(round.moved, target);
  round.backward = NearestPairs(target, round.moved);
  std::vector<double> all = round.forward.distance;
  all.insert(all.end(), round.backward.distance.begin(),
             round.backward.distance.end());
  round.residual = Quantile(all, 0.5) / spread;
  return round;
}

// Trimmed symmetric ICP with scale from `start`.
CloudAlignment RefineIcp(const Matrix3Xd& source, const Matrix3Xd& target,
                         double target_spread, SimilarityTransform start,
                         int iterations) {
  CloudAlignment result{start, 0};
  for (int it = 0; it <= iterations; ++it) {
    const IcpRound round =
        MatchBothWays(result.transform, source, target, target_spread);
    const Pairs& forward = round.forward;
    const Pairs& backward = round.backward;
    result.residual = round.residual;
    if (it == iterations) break;
    const size_t n = forward.query.size() + backward.query.size();
    Matrix3Xd from(3, n), to(3, n);
    size_t c = 0;
    for (size_t k = 0; k < forward.query.size(); ++k, ++c) {
      from.col(c) = source.col(forward.query[k]);
      to.col(c) = target.col(forward.neighbour[k]);
    }
    for (size_t k = 0; k < backward.query.size(); ++k, ++c) {
      from.col(c) = source.col(backward.neighbour[k]);
      to.col(c) = target.col(backward.query[k]);
    }
    const Eigen::Matrix4d m = Eigen::umeyama(from, to, true);
    const Matrix3d scaled = m.topLeftCorner<3, 3>();
    const double scale = std::cbrt(scaled.determinant());
    if (!(scale > 0) || !std::isfinite(scale)) break;  // collapsed: keep last
    result.transform.scale = scale;
    result.transform.rotation = scaled / scale;
    result.transform.translation = m.topRightCorner<3, 1>();
  }
  return result;
}

double AngleDegrees(const Matrix3d& rotation) {
  return Eigen::AngleAxisd(rotation).angle() * 180 / M_PI;
}

// The first `count` of `sorted` that differ from every earlier one kept
// (starts that converged to the same alignment).
std::vector<CloudAlignment> Distinct(const std::vector<CloudAlignment>& sorted,
                                     size_t count) {
  std::vector<CloudAlignment> kept;
  for (const CloudAlignment& a : sorted) {
    if (kept.size() == count) break;
    const bool seen = std::any_of(kept.begin(), kept.end(), [&](auto& k) {
      return std::abs(a.transform.scale / k.transform.scale - 1) < 0.01 &&
             AngleDegrees(a.transform.rotation *
                          k.transform.rotation.transpose()) < 2;
    });
    if (!seen) kept.push_back(a);
  }
  return kept;
}

// Unit normals of `points`: the least principal axis of each point's
// kNormalNeighbours nearest neighbours.
Matrix3Xd Normals(const Matrix3Xd& points) {
  const std::vector<float> xyz = ToFloats(points);
  const PointCloudAdaptor adaptor{xyz};
  const PointKdTree tree(3, adaptor,
                         nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const size_t k = std::min<size_t>(kNormalNeighbours, points.cols());
  Matrix3Xd normals(3, points.cols());
  std::vector<uint32_t> index(k);
  std::vector<float> d2(k);
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    tree.knnSearch(&xyz[3 * i], k, index.data(), d2.data());
    Vector3d mean = Vector3d::Zero();
    for (uint32_t j : index) mean += points.col(j) / double(k);
    Matrix3d covariance = Matrix3d::Zero();
    for (uint32_t j : index) {
      covariance += (points.col(j) - mean) * (points.col(j) - mean).transpose();
    }
    normals.col(i) = Eigen::SelfAdjointEigenSolver<Matrix3d>(covariance)
                         .eigenvectors()
                         .col(0);
  }
  return normals;
}

// One Gauss-Newton step of point-to-plane ICP with scale over `moved`
// (the source under the current transform, centred at `c`) and its pairs;
// the step as the similarity to compose after the current one.
SimilarityTransform PointToPlaneStep(const Matrix3Xd& moved,
                                     const Matrix3Xd& moved_normals,
                                     const Matrix3Xd& target,
                                     const Matrix3Xd& target_normals,
                                     const Pairs& forward,
                                     const Pairs& backward) {
  const Vector3d c = moved.rowwise().mean();
  Eigen::Matrix<double, 7, 7> jtj = Eigen::Matrix<double, 7, 7>::Zero();
  Eigen::Matrix<double, 7, 1> jtr = Eigen::Matrix<double, 7, 1>::Zero();
  const auto add = [&](const Vector3d& m, const Vector3d& q,
                       const Vector3d& n) {
    const Vector3d a = m - c;
    Eigen::Matrix<double, 7, 1> j;
    j << a.cross(n), n.dot(a), n;
    jtj += j * j.transpose();
    jtr += j * n.dot(m - q);
  };
  for (size_t k = 0; k < forward.query.size(); ++k) {
    add(moved.col(forward.query[k]), target.col(forward.neighbour[k]),
        target_normals.col(forward.neighbour[k]));
  }
  for (size_t k = 0; k < backward.query.size(); ++k) {
    add(moved.col(backward.neighbour[k]), target.col(backward.query[k]),
        moved_normals.col(backward.neighbour[k]));
  }
  jtj += 1e-9 * jtj.trace() * Eigen::Matrix<double, 7, 7>::Identity();
  const Eigen::Matrix<double, 7, 1> delta = jtj.ldlt().solve(-jtr);
  SimilarityTransform step;
  const Vector3d w = delta.head<3>();
  step.rotation =
      w.norm() > 0
          ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix()
          : Matrix3d::Identity();
  step.scale = 1 + delta[3];
  step.translation = c + delta.tail<3>() - step.scale * step.rotation * c;
  return step;
}

// Point-to-plane ICP with scale in both directions from `start`: converges
// in a few steps where point-to-point ICP crawls along the surfaces.
CloudAlignment RefinePointToPlane(const Matrix3Xd& source,
                                  const Matrix3Xd& target, double spread,
                                  const CloudAlignment& start, int iterations) {
  const Matrix3Xd source_normals = Normals(source);
  const Matrix3Xd target_normals = Normals(target);
  CloudAlignment result = start;
  for (int it = 0; it <= iterations; ++it) {
    const IcpRound round =
        MatchBothWays(result.transform, source, target, spread);
    const Pairs& forward = round.forward;
    const Pairs& backward = round.backward;
    const Matrix3Xd& moved = round.moved;
    result.residual = round.residual;
    if (it == iterations) break;
    const SimilarityTransform step =
        PointToPlaneStep(moved, result.transform.rotation * source_normals,
                         target, target_normals, forward, backward);
    if (!(step.scale > 0.5 && step.scale < 2)) break;  // diverging: keep last
    result.transform = step.After(result.transform);
  }
  return result;
}

std::vector<float> OpaqueMeans(const GaussianModel& model) {
  std::vector<float> xyz;
  for (size_t i = 0; i < model.size(); ++i) {
    if (OpacityLogitToAlpha(model.opacity_logits[i]) < kMinAlpha) continue;
    xyz.insert(xyz.end(), &model.means[3 * i], &model.means[3 * i + 3]);
  }
  return xyz.size() >= 30 ? xyz : model.means;
}

// Pearson's correlation of two equally long arrays; 0 if either is flat.
double Correlation(const std::vector<float>& a, const std::vector<float>& b) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sa += a[i], sb += b[i];
    saa += double(a[i]) * a[i], sbb += double(b[i]) * b[i];
    sab += double(a[i]) * b[i];
  }
  const double n = double(a.size());
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  if (!(va > 1e-12 * n) || !(vb > 1e-12 * n)) return 0;
  return (sab - sa * sb / n) / std::sqrt(va * vb);
}

// `count` views spread over the training split (the views train and embed
// --split train hold out are left out): the fit never sees a photo that a
// held-out figure is measured on.
std::vector<size_t> ProbeViews(const TrainingViews& views, int count) {
  std::vector<size_t> pool;
  for (size_t v = 0; v < views.NumViews(); ++v) {
    if (!views.HeldOut(v) || views.NumViews() == 1) pool.push_back(v);
  }
  std::vector<size_t> out;
  const size_t n = std::min<size_t>(std::max(count, 1), pool.size());
  for (size_t k = 0; k < n; ++k) out.push_back(pool[k * pool.size() / n]);
  return out;
}

// The camera rendering `camera`'s view at `factor` of its size.
RenderCamera Shrunk(const RenderCamera& camera, double factor) {
  RenderCamera small = camera;
  small.width = std::max(1, int(std::lround(camera.width * factor)));
  small.height = std::max(1, int(std::lround(camera.height * factor)));
  const double fx = double(small.width) / camera.width;
  const double fy = double(small.height) / camera.height;
  small.fx *= fx, small.cx *= fx, small.fy *= fy, small.cy *= fy;
  return small;
}

// A small similarity about `centre`, from 7 parameters in pixels at the
// probes' focal length and depth: rotation (3), scale (1), translation (3).
SimilarityTransform Correction(const double* x, const Vector3d& centre,
                               double focal, double depth) {
  const Vector3d w = Vector3d(x[0], x[1], x[2]) / focal;
  SimilarityTransform c;
  c.rotation = w.norm() > 0
                   ? Eigen::AngleAxisd(w.norm(), w.normalized()).matrix()
                   : Matrix3d::Identity();
  c.scale = std::exp(x[3] / focal);
  c.translation = centre + Vector3d(x[4], x[5], x[6]) * depth / focal -
                  c.scale * c.rotation * centre;
  return c;
}

// The blurred renders at the probes through `base` after a correction,
// minus the blurred photos; forward differences over renders.
class SimilarityPhotoCost : public ceres::CostFunction {
 public:
  struct Setup {
    Rasterizer* rasterizer;
    const GaussianModel* model;
    const TrainingViews* views;
    std::vector<size_t> probes;
    std::array<float, 3> background;
    SimilarityTransform base;
    Vector3d centre;
    double focal = 1, depth = 1;
    // Renders and photos are fitted at this fraction of their size.
    double shrink = 1;
  };
  SimilarityPhotoCost(const Setup& setup, std::vector<float> target)
      : setup_(setup), target_(std::move(target)) {
    set_num_residuals(int(target_.size()));
    mutable_parameter_block_sizes()->push_back(7);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Residuals(parameters[0], residuals);
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    std::vector<double> moved(target_.size());
    for (int j = 0; j < 7; ++j) {
      double y[7];
      std::copy(parameters[0], parameters[0] + 7, y);
      y[j] += kStepPx;
      Residuals(y, moved.data());
      for (size_t i = 0; i < target_.size(); ++i) {
        jacobians[0][i * 7 + j] = (moved[i] - residuals[i]) / kStepPx;
      }
    }
    return true;
  }
  SimilarityTransform Transform(const double* x) const {
    return setup_.base.After(
        Correction(x, setup_.centre, setup_.focal, setup_.depth));
  }
  // The probes' blurred photos at the fit's size, concatenated.
  static std::vector<float> Target(const Setup& setup) {
    std::vector<float> target;
    for (size_t v : setup.probes) {
      const std::shared_ptr<const ImageRGB> photo = setup.views->Image(v);
      const RenderCamera small = Shrunk(setup.views->Camera(v), setup.shrink);
      ImageRGB resized(small.width, small.height);
      cv::Mat out(small.height, small.width, CV_32FC3, resized.data.data());
      cv::resize(cv::Mat(photo->height, photo->width, CV_32FC3,
                         const_cast<float*>(photo->data.data())),
                 out, cv::Size(small.width, small.height), 0, 0,
                 cv::INTER_AREA);
      const std::vector<float> b = Blurred(resized, kBlurPx);
      target.insert(target.end(), b.begin(), b.end());
    }
    return target;
  }

 private:
  static constexpr double kStepPx = 0.25, kBlurPx = 1.0;
  void Residuals(const double* x, double* out) const {
    const AlignedViews moved(*setup_.views, Transform(x));
    RenderOptions options;
    options.background = setup_.background;
    ImageRGB image;
    size_t offset = 0;
    for (size_t v : setup_.probes) {
      setup_.rasterizer->Forward(*setup_.model,
                                 Shrunk(moved.Camera(v), setup_.shrink),
                                 options, &image, nullptr);
      for (float& c : image.data) c = std::clamp(c, 0.f, 1.f);
      const std::vector<float> b = Blurred(image, kBlurPx);
      for (size_t i = 0; i < b.size(); ++i, ++offset) {
        out[offset] = double(b[i]) - double(target_[offset]);
      }
    }
  }
  const Setup& setup_;
  const std::vector<float> target_;
};

// ICP places a model to a few tenths of a percent of the scene, a pixel or
// two at the photos (OpenSplat's demo model: 20.9 dB against the photos
// where its exact frame reads 25.8); the renders themselves finish the fit:
// Levenberg-Marquardt on the similarity over the blurred probe views.
SimilarityTransform RefineSimilarity(Rasterizer& rasterizer,
                                     const GaussianModel& model,
                                     const TrainingViews& views,
                                     const std::vector<size_t>& probes,
                                     const std::vector<float>& sfm_points,
                                     const SimilarityTransform& start,
                                     const std::array<float, 3>& background) {
  SimilarityPhotoCost::Setup setup{&rasterizer, &model,     &views,
                                   probes,      background, start};
  const Matrix3Xd points = Subsample(sfm_points, kSearchPoints);
  setup.centre = points.rowwise().mean();
  const RenderCamera first = views.Camera(probes.front());
  // At most kRefineWidth pixels wide: memory and time stay bounded at any
  // photo size (a 12 MP photo would give 10^8 residuals).
  setup.shrink = std::min(1.0, kRefineWidth / double(first.width));
  setup.focal = first.fx * setup.shrink;
  setup.depth = (first.Center() - setup.centre).norm();
  double x[7] = {0, 0, 0, 0, 0, 0, 0};
  ceres::Problem problem;
  problem.AddResidualBlock(
      new SimilarityPhotoCost(setup, SimilarityPhotoCost::Target(setup)),
      nullptr, x);
  ceres::Solver::Options solver;
  solver.max_num_iterations = 8;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  SimilarityPhotoCost cost(setup, {});
  return cost.Transform(x);
}

}  // namespace

RenderCamera AlignedViews::Camera(size_t view) const {
  return TransformCamera(base_.Camera(view), transform_);
}

SimilarityTransform Inverse(const SimilarityTransform& t) {
  SimilarityTransform inverse;
  inverse.scale = 1 / t.scale;
  inverse.rotation = t.rotation.transpose();
  inverse.translation = -inverse.rotation * t.translation / t.scale;
  return inverse;
}

PhotoMatch MatchPhotos(Rasterizer& rasterizer, const GaussianModel& model,
                       const TrainingViews& views,
                       const std::vector<size_t>& view_ids,
                       const std::array<float, 3>& background) {
  PhotoMatch match;
  ImageRGB image;
  RenderOptions options;
  options.background = background;
  for (size_t v : view_ids) {
    rasterizer.Forward(model, views.Camera(v), options, &image, nullptr);
    for (float& x : image.data) x = std::clamp(x, 0.f, 1.f);
    const std::shared_ptr<const ImageRGB> photo = views.Image(v);
    match.psnr += Psnr(image, *photo) / view_ids.size();
    match.correlation += Correlation(image.data, photo->data) / view_ids.size();
  }
  return match;
}

std::vector<CloudAlignment> AlignPointClouds(const std::vector<float>& source,
                                             const std::vector<float>& target,
                                             int keep) {
  if (source.size() < 30 || target.size() < 30) {
    Fail("align point clouds: fewer than 10 points");
  }
  const Matrix3Xd src = Subsample(source, kSearchPoints);
  const Matrix3Xd tgt = Subsample(target, kSearchPoints);
  const Matrix3Xd coarse_src = Subsample(source, kCoarsePoints);
  const Matrix3Xd coarse_tgt = Subsample(target, kCoarsePoints);
  const Frame fs = PrincipalFrame(src), ft = PrincipalFrame(tgt);
  if (!(fs.spread > 0) || !(ft.spread > 0)) {
    Fail("align point clouds: a cloud has collapsed to a point");
  }
  // Starts: the principal frames matched every way, the world's axes (for
  // normalisations that only permute or flip them), and rotations spread
  // over all of them (clouds whose principal axes are not distinct).
  std::vector<Matrix3d> rotations;
  for (const Matrix3d& q : AxisRotations()) {
    rotations.push_back(ft.axes * q * fs.axes.transpose());
    rotations.push_back(q);
  }
  std::mt19937 rng(1);
  std::normal_distribution<double> normal;
  for (int k = 0; k < kSpreadStarts; ++k) {
    rotations.push_back(
        Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
            .normalized()
            .toRotationMatrix());
  }
  std::vector<CloudAlignment> found;
  for (const Matrix3d& rotation : rotations) {
    SimilarityTransform start;
    start.scale = ft.spread / fs.spread;
    start.rotation = rotation;
    start.translation = ft.centre - start.scale * rotation * fs.centre;
    found.push_back(RefineIcp(coarse_src, coarse_tgt, ft.spread, start, 10));
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return a.residual < b.residual;
  });
  found = Distinct(found, 2 * keep);
  for (CloudAlignment& a : found) {
    a = RefineIcp(src, tgt, ft.spread, a.transform, 10);
    a = RefinePointToPlane(src, tgt, ft.spread, a, 15);
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return a.residual < b.residual;
  });
  found.resize(std::min<size_t>(found.size(), keep));
  return found;
}

ModelPlacement PlaceModel(Rasterizer& rasterizer, const GaussianModel& model,
                          const std::string& model_path,
                          const TrainingViews& views,
                          const std::vector<float>& sfm_points,
                          const PlacementOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  ModelPlacement p;
  const std::vector<size_t> probes = ProbeViews(views, options.probe_views);
  p.num_probe_views = probes.size();
  const PhotoMatch given =
      MatchPhotos(rasterizer, model, views, probes, options.background);
  p.psnr_as_given = p.psnr_placed = given.psnr;
  p.correlation_as_given = p.correlation_placed = given.correlation;
  const auto finish = [&] {
    p.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
  };
  if (p.correlation_as_given >= options.align_below_correlation) {
    finish();
    return p;
  }
  if (sfm_points.size() >= 30 && model.size() >= 10) {
    for (const CloudAlignment& a :
         AlignPointClouds(sfm_points, OpaqueMeans(model), 3)) {
      const AlignedViews moved(views, a.transform);
      const PhotoMatch match =
          MatchPhotos(rasterizer, model, moved, probes, options.background);
      if (match.correlation > p.correlation_placed + 0.05) {
        p.psnr_placed = match.psnr;
        p.correlation_placed = match.correlation;
        p.workspace_to_model = a.transform;
        p.residual = a.residual;
        p.moved = true;
      }
    }
  }
  // Only a placement that already matches is refined: with 7 degrees of
  // freedom the fit also lines up another scene's blobs with the photos (the
  // tests' foreign model: 0.27 -> 0.47), so what is refused is judged before.
  if (p.moved && p.correlation_placed >= kRefineAboveCorrelation) {
    const SimilarityTransform refined =
        RefineSimilarity(rasterizer, model, views, probes, sfm_points,
                         p.workspace_to_model, options.background);
    const PhotoMatch match =
        MatchPhotos(rasterizer, model, AlignedViews(views, refined), probes,
                    options.background);
    if (match.correlation > p.correlation_placed) {
      p.workspace_to_model = refined;
      p.psnr_placed = match.psnr;
      p.correlation_placed = match.correlation;
    }
  }
  finish();
  if (options.refuse &&
      p.correlation_placed < options.refuse_below_correlation) {
    char after[160] = " and no alignment to the SfM points did better";
    if (p.moved) {
      std::snprintf(after, sizeof(after),
                    ", %.2f (%.1f dB) at best after aligning it to the SfM "
                    "points",
                    p.correlation_placed, p.psnr_placed);
    }
    char line[640];
    std::snprintf(
        line, sizeof(line),
        "does not match the workspace's photos: its renders correlate %.2f "
        "with them (PSNR %.1f dB) at %zu cameras as given%s, where a model "
        "trained on these photos correlates %.1f or more; likely another "
        "scene's model, or another workspace or --downscale than it was "
        "trained on",
        p.correlation_as_given, p.psnr_as_given, p.num_probe_views, after,
        options.align_below_correlation);
    FailAt(model_path, line);
  }
  return p;
}

std::string DescribePlacement(const ModelPlacement& p) {
  char line[640];
  if (!p.moved) {
    std::snprintf(line, sizeof(line),
                  "the model matches the workspace's photos (PSNR %.2f dB, "
                  "correlation %.3f at %zu cameras, %.1f s)",
                  p.psnr_as_given, p.correlation_as_given, p.num_probe_views,
                  p.seconds);
    return line;
  }
  const SimilarityTransform to_workspace = Inverse(p.workspace_to_model);
  const Vector3d& t = to_workspace.translation;
  std::snprintf(
      line, sizeof(line),
      "the model is in another frame and was aligned to the workspace: "
      "scale %.5g, rotation %.2f deg, translation (%.4g, %.4g, %.4g) "
      "(model -> workspace); against the photos at %zu cameras PSNR %.2f "
      "-> %.2f dB, correlation %.3f -> %.3f; point residual %.2f%% of the "
      "scene, %.1f s; the model itself is not moved (the cameras are)",
      to_workspace.scale, AngleDegrees(to_workspace.rotation), t[0], t[1], t[2],
      p.num_probe_views, p.psnr_as_given, p.psnr_placed, p.correlation_as_given,
      p.correlation_placed, 100 * p.residual, p.seconds);
  return line;
}

void ScaleToModelUnits(const ModelPlacement& placement,
                       std::vector<DistortionSpec>* layers) {
  for (DistortionSpec& spec : *layers) {
    if (spec.kind == DistortionKind::kGaussianNoise) {
      spec.strength *= placement.workspace_to_model.scale;
    }
  }
}

void ScaleToModelUnits(const ModelPlacement& placement,
                       std::vector<ModelAttackSpec>* attacks) {
  for (ModelAttackSpec& spec : *attacks) {
    if (spec.kind != ModelAttackKind::kDistortion) continue;
    std::vector<DistortionSpec> one = {spec.distortion};
    ScaleToModelUnits(placement, &one);
    spec.distortion = one[0];
  }
}

const char kAlignHelp[] =
    "auto: render the model at a few cameras first and, when it does not "
    "match the photos (a model saved in a trainer's normalised frame), find "
    "the similarity from its Gaussians to the SfM points and render the "
    "cameras moved into the model's frame (the model is never moved); off: "
    "take it as it is; or similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ] (or a "
    ".transform.txt file): the transform the model was moved by from the "
    "workspace's frame";

SimilarityTransform ParseSceneTransform(const std::string& value,
                                        const std::string& option) {
  const std::string prefix = "similarity:";
  std::string text = value;
  std::string source = option;
  if (std::filesystem::is_regular_file(value)) {
    const std::vector<uint8_t> bytes = ReadFileBytes(value);
    text.assign(bytes.begin(), bytes.end());
    while (!text.empty() && std::isspace((unsigned char)text.back())) {
      text.pop_back();
    }
    source = value;
  } else if (text.rfind(prefix, 0) != 0 &&
             text.find_first_not_of("0123456789+-.,eE ") != std::string::npos) {
    // Neither numbers nor an existing file: a mistyped file name.
    FailAt(value, option +
                      " file not found (give the .transform.txt that watergs "
                      "attack wrote, or similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ])");
  }
  if (text.rfind(prefix, 0) == 0) text = text.substr(prefix.size());
  try {
    return ParseSimilarity(text);
  } catch (const Error& e) {
    std::string message = e.what();
    const std::string attack = "--attack: ";
    if (message.rfind(attack, 0) == 0) message = message.substr(attack.size());
    Fail(source + ": " + message);
  }
}

PlacedViews PlaceByOption(const std::string& command, const std::string& align,
                          Rasterizer& rasterizer, const GaussianModel& model,
                          const std::string& model_path,
                          const Workspace& workspace,
                          const TrainingViews& views,
                          const std::array<float, 3>& background,
                          bool suspect) {
  PlacedViews placed;
  placed.base = &views;
  if (align == "off") return placed;
  if (align != "auto") {
    placed.placement.workspace_to_model = ParseSceneTransform(align, "--align");
    placed.placement.moved = true;
    placed.aligned = std::make_unique<AlignedViews>(
        views, placed.placement.workspace_to_model);
    std::printf("%s: cameras moved into the model's frame by --align %s\n",
                command.c_str(), align.c_str());
    return placed;
  }
  if (!workspace.has_images()) {
    std::printf(
        "%s: the model was not checked against the photos (the workspace "
        "has none); --align SIMILARITY if it was saved in another frame\n",
        command.c_str());
    return placed;
  }
  std::vector<float> xyz, rgb;
  workspace.PointCloud(&xyz, &rgb);
  PlacementOptions options;
  options.background = background;
  options.refuse = !suspect;
  placed.placement =
      PlaceModel(rasterizer, model, model_path, views, xyz, options);
  if (suspect &&
      placed.placement.correlation_placed < options.refuse_below_correlation) {
    // No similarity is trusted that leaves it unmatched: read where it is.
    ModelPlacement& p = placed.placement;
    p.workspace_to_model = SimilarityTransform();
    p.moved = false;
    p.psnr_placed = p.psnr_as_given;
    p.correlation_placed = p.correlation_as_given;
    std::fprintf(stderr,
                 "%s: %s correlates %.2f with the photos (PSNR %.1f dB): "
                 "damaged by an attack, or not of this scene\n",
                 command.c_str(), model_path.c_str(),
                 placed.placement.correlation_placed,
                 placed.placement.psnr_placed);
  }
  if (placed.placement.moved) {
    placed.aligned = std::make_unique<AlignedViews>(
        views, placed.placement.workspace_to_model);
  }
  std::printf("%s: %s\n", command.c_str(),
              DescribePlacement(placed.placement).c_str());
  return placed;
}

}  // namespace watergs
