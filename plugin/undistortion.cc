// Undistortion to pinhole cameras: COLMAP's default output intrinsics and
// OpenCV remapping through the COLMAP model functions.
#include "plugin/undistortion.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace watergs {

namespace {

// Extremes of the undistorted positions of one image border.
struct BorderRange {
  double min = std::numeric_limits<double>::max();
  double max = std::numeric_limits<double>::lowest();
  void Add(double value) {
    min = std::min(min, value);
    max = std::max(max, value);
  }
};

// Position of distorted pixel (x, y) in the pinhole camera.
Eigen::Vector2d ToPinhole(const Camera& distorted, const Camera& pinhole,
                          double x, double y) {
  return pinhole.WorldToImage(distorted.ImageToWorld(Eigen::Vector2d(x, y)));
}

// Scale along one axis: 1 / interpolation of the "keep all pixels" and "no
// blank pixels" scales, clipped to the options' bounds.
double AxisScale(double c, double size, const BorderRange& low,
                 const BorderRange& high,
                 const UndistortCameraOptions& options) {
  const double keep_all =
      std::min(c / (c - low.min), (size - 0.5 - c) / (high.max - c));
  const double no_blank =
      std::max(c / (c - low.max), (size - 0.5 - c) / (high.min - c));
  const double scale = 1.0 / (keep_all * options.blank_pixels +
                              no_blank * (1.0 - options.blank_pixels));
  return std::clamp(scale, options.min_scale, options.max_scale);
}

}  // namespace

Camera UndistortCamera(const Camera& camera,
                       const UndistortCameraOptions& options) {
  Camera pinhole;
  pinhole.camera_id = camera.camera_id;
  pinhole.model_id = PinholeCameraModel::kModelId;
  pinhole.width = camera.width;
  pinhole.height = camera.height;
  pinhole.params = {camera.FocalLengthX(), camera.FocalLengthY(),
                    camera.PrincipalPointX(), camera.PrincipalPointY()};
  if (!camera.HasDistortion()) return pinhole;

  const double w = camera.width, h = camera.height;
  BorderRange left, right, top, bottom;
  for (uint64_t y = 0; y < camera.height; ++y) {
    left.Add(ToPinhole(camera, pinhole, 0.5, y + 0.5).x());
    right.Add(ToPinhole(camera, pinhole, w - 0.5, y + 0.5).x());
  }
  for (uint64_t x = 0; x < camera.width; ++x) {
    top.Add(ToPinhole(camera, pinhole, x + 0.5, 0.5).y());
    bottom.Add(ToPinhole(camera, pinhole, x + 0.5, h - 0.5).y());
  }
  const double cx = pinhole.params[2], cy = pinhole.params[3];
  const double scale_x = AxisScale(cx, w, left, right, options);
  const double scale_y = AxisScale(cy, h, top, bottom, options);
  // Truncation, not rounding, as COLMAP does.
  pinhole.width = static_cast<uint64_t>(std::max(1.0, scale_x * w));
  pinhole.height = static_cast<uint64_t>(std::max(1.0, scale_y * h));
  pinhole.params[2] = cx * static_cast<double>(pinhole.width) / w;
  pinhole.params[3] = cy * static_cast<double>(pinhole.height) / h;
  return pinhole;
}

WarpMap ComputeWarpMap(const Camera& source, const Camera& target) {
  const int width = target.width, height = target.height;
  WarpMap map{cv::Mat(height, width, CV_32FC1),
              cv::Mat(height, width, CV_32FC1)};
#pragma omp parallel for schedule(static)
  for (int row = 0; row < height; ++row) {
    float* map_x = map.map_x.ptr<float>(row);
    float* map_y = map.map_y.ptr<float>(row);
    for (int col = 0; col < width; ++col) {
      const Eigen::Vector2d uv =
          target.ImageToWorld(Eigen::Vector2d(col + 0.5, row + 0.5));
      const Eigen::Vector2d xy = source.WorldToImage(uv);
      // COLMAP pixel centres are at +0.5, OpenCV's at integers.
      map_x[col] = std::isfinite(xy.x()) ? float(xy.x() - 0.5) : -1e6f;
      map_y[col] = std::isfinite(xy.y()) ? float(xy.y() - 0.5) : -1e6f;
    }
  }
  return map;
}

cv::Mat WarpImage(const cv::Mat& image, const WarpMap& map) {
  cv::Mat warped;
  cv::remap(image, warped, map.map_x, map.map_y, cv::INTER_LINEAR,
            cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return warped;
}

}  // namespace watergs
