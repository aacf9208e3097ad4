// Undistortion of COLMAP cameras to pinhole ones, for rendering: distorted
// cameras get the PINHOLE camera `colmap image_undistorter` computes with its
// default options (blank_pixels 0, min_scale 0.2, max_scale 2): focal lengths
// kept, size and principal point scaled so that no blank pixel remains.
// Images are warped with maps computed from the COLMAP model functions
// (bilinear, black outside the source). Pinhole cameras need none of this.
#pragma once

#include <opencv2/core.hpp>

#include "plugin/reconstruction.h"

namespace watergs {

struct UndistortCameraOptions {
  // 0: no blank pixels in the output; 1: every source pixel kept.
  double blank_pixels = 0.0;
  // Bounds on the output/input size ratio.
  double min_scale = 0.2;
  double max_scale = 2.0;
};

// The PINHOLE camera (model id 1, same camera_id) to render `camera` with.
// SIMPLE_PINHOLE/PINHOLE inputs come back with identical intrinsics.
Camera UndistortCamera(const Camera& camera,
                       const UndistortCameraOptions& options = {});

// For each pixel of `target`, where it lies in `source` (both cameras see
// the same rays): CV_32FC1 maps in OpenCV's pixel convention (pixel centres
// at integers), ready for cv::remap.
struct WarpMap {
  // Source x and y for each target pixel, target height x width.
  cv::Mat map_x;
  cv::Mat map_y;
};
WarpMap ComputeWarpMap(const Camera& source, const Camera& target);

// Warps `image` (any type OpenCV remaps; size of the source camera) to the
// target camera of `map`: bilinear, black outside the source.
cv::Mat WarpImage(const cv::Mat& image, const WarpMap& map);

}  // namespace watergs
