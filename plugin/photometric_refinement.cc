#include "plugin/photometric_refinement.h"

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <utility>
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
// The Jacobian: from the image gradient where a depth map of the start is
// given (GradientJacobian), else a forward difference over renders, steps of
// `step_px` (each parameter is scaled to pixels, so one step fits all).
class RenderAlignmentCost : public ceres::CostFunction {
 public:
  // The first `free` of the 9 parameters move (6: the pose alone).
  RenderAlignmentCost(const std::vector<float>& target,
                      const RenderCamera& camera, double depth, int free,
                      const CameraRenderer& render,
                      const PhotometricOptions& options, int* renders,
                      std::vector<float> depth_map = {})
      : free_(free),
        target_(target),
        camera_(camera),
        depth_(depth),
        render_(render),
        options_(options),
        renders_(renders),
        depth_map_(std::move(depth_map)) {
    set_num_residuals(int(target.size()));
    mutable_parameter_block_sizes()->push_back(free);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    double x[kParameters] = {0};
    std::copy(parameters[0], parameters[0] + free_, x);
    const std::vector<float> blurred = BlurredRender(x);
    // A render of another size cannot be compared: the step is refused.
    if (!Difference(blurred, residuals)) return false;
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    if (depth_map_.size() * 3 == target_.size()) {
      const std::vector<double> jacobian =
          GradientJacobian(blurred, depth_map_, camera_, depth_, x, free_);
      std::copy(jacobian.begin(), jacobian.end(), jacobians[0]);
      return true;
    }
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

  // x: all 9 parameters. A render of another size reads as no fit at all.
  void Residuals(const double* x, double* out) const {
    if (!Difference(BlurredRender(x), out)) {
      std::fill(out, out + target_.size(), 1.0);
    }
  }

 private:
  // out = blurred - target; false (out untouched) when the sizes differ.
  bool Difference(const std::vector<float>& blurred, double* out) const {
    if (blurred.size() != target_.size()) return false;
    for (size_t i = 0; i < target_.size(); ++i) {
      out[i] = double(blurred[i]) - double(target_[i]);
    }
    return true;
  }

  std::vector<float> BlurredRender(const double* x) const {
    const ImageRGB rendered = render_(MoveCamera(camera_, depth_, x));
    ++*renders_;
    return Blurred(rendered, options_.blur_sigma);
  }

  const int free_;
  const std::vector<float>& target_;
  const RenderCamera camera_;
  const double depth_;
  const CameraRenderer& render_;
  const PhotometricOptions options_;
  int* renders_;
  const std::vector<float> depth_map_;
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

std::vector<double> GradientJacobian(const std::vector<float>& blurred,
                                     const std::vector<float>& depth_map,
                                     const RenderCamera& camera, double depth,
                                     const double* x, int free) {
  const int w = camera.width, h = camera.height;
  const size_t pixels = size_t(w) * h;
  if (blurred.size() != 3 * pixels || depth_map.size() != pixels ||
      !(depth > 0) || !std::isfinite(depth)) {
    throw std::invalid_argument(
        "GradientJacobian: the render must be H x W x 3 and the depth map H "
        "x W of the camera, with a positive typical depth");
  }
  const RenderCamera at = MoveCamera(camera, depth, x);
  // A pixel's image motion under parameter j: where its point (at its depth)
  // projects once the camera takes a small step in j, in double.
  constexpr double kStep = 1e-4;
  std::vector<RenderCamera> stepped;
  for (int j = 0; j < free; ++j) {
    double y[kParameters];
    std::copy(x, x + kParameters, y);
    y[j] += kStep;
    stepped.push_back(MoveCamera(camera, depth, y));
  }
  std::vector<double> jacobian(blurred.size() * size_t(free), 0.0);
  for (int v = 0; v < h; ++v) {
    const int v0 = std::max(v - 1, 0), v1 = std::min(v + 1, h - 1);
    for (int u = 0; u < w; ++u) {
      const int u0 = std::max(u - 1, 0), u1 = std::min(u + 1, w - 1);
      const size_t p = size_t(v) * w + u;
      double z = depth_map[p];
      if (!(z > 0) || !std::isfinite(z)) z = depth;
      // The pixel's centre (gaussian/camera.h: col + 0.5, row + 0.5).
      const double pu = u + 0.5, pv = v + 0.5;
      const Eigen::Vector3d in_at((pu - at.cx) / at.fx * z,
                                  (pv - at.cy) / at.fy * z, z);
      const Eigen::Vector3d world = at.R.transpose() * (in_at - at.t);
      double gx[3], gy[3];
      for (int c = 0; c < 3; ++c) {
        gx[c] = (double(blurred[(size_t(v) * w + u1) * 3 + c]) -
                 double(blurred[(size_t(v) * w + u0) * 3 + c])) /
                std::max(1, u1 - u0);
        gy[c] = (double(blurred[(size_t(v1) * w + u) * 3 + c]) -
                 double(blurred[(size_t(v0) * w + u) * 3 + c])) /
                std::max(1, v1 - v0);
      }
      for (int j = 0; j < free; ++j) {
        const RenderCamera& s = stepped[j];
        const Eigen::Vector3d in_s = s.R * world + s.t;
        if (!(in_s.z() > 0)) continue;
        const double du = (s.fx * in_s.x() / in_s.z() + s.cx - pu) / kStep;
        const double dv = (s.fy * in_s.y() / in_s.z() + s.cy - pv) / kStep;
        // The render moved by (du, dv): its value at a pixel is what was
        // (du, dv) before it.
        for (int c = 0; c < 3; ++c) {
          jacobian[(p * 3 + c) * free + j] = -(gx[c] * du + gy[c] * dv);
        }
      }
    }
  }
  return jacobian;
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
  std::vector<float> depth_map;
  if (options.depth_map) {
    depth_map = options.depth_map(start);
    ++*renders;
    if (depth_map.size() != size_t(start.width) * start.height) {
      depth_map.clear();  // not this camera's: finite differences
    }
  }
  auto* cost = new RenderAlignmentCost(target, start, depth, free, render,
                                       options, renders, std::move(depth_map));
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
