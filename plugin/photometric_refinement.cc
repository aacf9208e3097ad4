#include "plugin/photometric_refinement.h"

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace watergs {
namespace {

constexpr int kParameters = 9;

}  // namespace

std::vector<float> Blurred(const ImageRGB& image, double sigma) {
  cv::Mat rgb(image.height, image.width, CV_32FC3,
              const_cast<float*>(image.data.data()));
  cv::Mat out;
  if (sigma > 0) {
    cv::GaussianBlur(rgb, out, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  } else {
    out = rgb.clone();
  }
  const float* p = out.ptr<float>(0);
  return std::vector<float>(p, p + image.data.size());
}

namespace {

double Rms(const std::vector<double>& r) {
  double sum = 0;
  for (double v : r) sum += v * v;
  return std::sqrt(sum / std::max<size_t>(1, r.size()));
}

// Residuals: the blurred render at the moved camera minus the blurred image.
// The Jacobian is a forward difference over renders, steps of `step_px`
// (each parameter is scaled to pixels, so one step fits all).
class RenderAlignmentCost : public ceres::CostFunction {
 public:
  // The first `free` of the 9 parameters move (6: the pose alone).
  RenderAlignmentCost(const std::vector<float>& target,
                      const RenderCamera& camera, double depth, int free,
                      const CameraRenderer& render,
                      const PhotometricOptions& options, int* renders)
      : free_(free),
        target_(target),
        camera_(camera),
        depth_(depth),
        render_(render),
        options_(options),
        renders_(renders) {
    set_num_residuals(int(target.size()));
    mutable_parameter_block_sizes()->push_back(free);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    double x[kParameters] = {0};
    std::copy(parameters[0], parameters[0] + free_, x);
    Residuals(x, residuals);
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    const size_t n = target_.size();
    std::vector<double> moved(n);
    for (int j = 0; j < free_; ++j) {
      double y[kParameters];
      std::copy(x, x + kParameters, y);
      y[j] += options_.step_px;
      Residuals(y, moved.data());
      for (size_t i = 0; i < n; ++i) {
        jacobians[0][i * free_ + j] =
            (moved[i] - residuals[i]) / options_.step_px;
      }
    }
    return true;
  }

  // x: all 9 parameters.
  void Residuals(const double* x, double* out) const {
    const ImageRGB rendered = render_(MoveCamera(camera_, depth_, x));
    ++*renders_;
    const std::vector<float> blurred = Blurred(rendered, options_.blur_sigma);
    for (size_t i = 0; i < target_.size(); ++i) {
      out[i] = double(blurred[i]) - double(target_[i]);
    }
  }

 private:
  const int free_;
  const std::vector<float>& target_;
  const RenderCamera camera_;
  const double depth_;
  const CameraRenderer& render_;
  const PhotometricOptions options_;
  int* renders_;
};

}  // namespace

RenderCamera MoveCamera(const RenderCamera& camera, double depth,
                        const double* delta) {
  RenderCamera moved = camera;
  const Eigen::Vector3d omega(delta[0], delta[1], delta[2]);
  const Eigen::Vector3d w = omega / camera.fx;
  const Eigen::Matrix3d turn =
      w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).matrix()
                   : Eigen::Matrix3d::Identity();
  moved.R = turn * camera.R;
  moved.t = turn * camera.t +
            Eigen::Vector3d(delta[3], delta[4], delta[5]) * depth / camera.fx;
  const double scale = 1 + 2 * delta[6] / camera.width;
  moved.fx = camera.fx * scale;
  moved.fy = camera.fy * scale;
  moved.cx = camera.cx + delta[7];
  moved.cy = camera.cy + delta[8];
  return moved;
}

double CameraMotionPx(const RenderCamera& a, const RenderCamera& b,
                      double depth) {
  double worst = 0;
  const double us[3] = {0, a.width / 2.0, double(a.width)};
  const double vs[3] = {0, a.height / 2.0, double(a.height)};
  for (double u : us) {
    for (double v : vs) {
      const Eigen::Vector3d in_a((u - a.cx) / a.fx * depth,
                                 (v - a.cy) / a.fy * depth, depth);
      const Eigen::Vector3d world = a.R.transpose() * (in_a - a.t);
      const Eigen::Vector3d in_b = b.R * world + b.t;
      if (in_b.z() <= 0) return INFINITY;
      const double ub = b.fx * in_b.x() / in_b.z() + b.cx;
      const double vb = b.fy * in_b.y() / in_b.z() + b.cy;
      worst = std::max(worst, std::hypot(ub - u, vb - v));
    }
  }
  return worst;
}

namespace {

// Levenberg-Marquardt over the first `free` parameters from `start`; returns
// the moved camera and its residual RMS.
std::pair<RenderCamera, double> Align(const std::vector<float>& target,
                                      const RenderCamera& start, double depth,
                                      int free, const CameraRenderer& render,
                                      const PhotometricOptions& options,
                                      int* renders) {
  auto* cost = new RenderAlignmentCost(target, start, depth, free, render,
                                       options, renders);
  double x[kParameters] = {0};
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, x);
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  solver.logging_type = ceres::SILENT;
  solver.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  std::vector<double> residuals(target.size());
  cost->Residuals(x, residuals.data());
  return {MoveCamera(start, depth, x), Rms(residuals)};
}

}  // namespace

PhotometricResult RefinePhotometrically(const ImageRGB& image,
                                        const std::vector<RenderCamera>& starts,
                                        double depth,
                                        const CameraRenderer& render,
                                        const PhotometricOptions& options) {
  PhotometricResult result;
  if (starts.empty()) return result;
  const RenderCamera& camera = starts[0];
  result.camera = camera;
  if (!(depth > 0) || !std::isfinite(depth)) return result;
  for (const RenderCamera& s : starts) {
    if (image.width != s.width || image.height != s.height) return result;
  }
  const std::vector<float> target = Blurred(image, options.blur_sigma);
  {
    RenderAlignmentCost cost(target, camera, depth, kParameters, render,
                             options, &result.renders);
    const double zero[kParameters] = {0};
    std::vector<double> residuals(target.size());
    cost.Residuals(zero, residuals.data());
    result.rms_before = Rms(residuals);
  }
  // The pose alone from each start (intrinsics and pose trade against each
  // other, and a start's intrinsics may be the right ones), then everything
  // from the best.
  std::pair<RenderCamera, double> best{camera, INFINITY};
  int best_start = 0;
  for (size_t k = 0; k < starts.size(); ++k) {
    auto aligned =
        Align(target, starts[k], depth, 6, render, options, &result.renders);
    if (aligned.second < best.second) best = aligned, best_start = int(k);
  }
  if (options.refine_intrinsics) {
    auto aligned = Align(target, best.first, depth, kParameters, render,
                         options, &result.renders);
    if (aligned.second < (1 - options.intrinsics_gain) * best.second) {
      best = aligned;
    }
  }
  // A wrong basin shows as a long move from the start the alignment left
  // (another start may lie far from the first and still be right).
  const double moved = CameraMotionPx(starts[best_start], best.first, depth);
  if (std::isfinite(best.second) && best.second < result.rms_before &&
      moved <= options.max_move_px) {
    result.applied = true;
    result.moved_px = moved;
    result.start = best_start;
    result.camera = best.first;
    result.rms_after = best.second;
  } else {
    result.rms_after = result.rms_before;
  }
  return result;
}

}  // namespace watergs
