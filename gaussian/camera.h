// The camera the rasterizer renders from: pinhole intrinsics and a
// world-to-camera pose. Distorted COLMAP cameras are undistorted to this
// model before rendering (plugin/undistortion.h).
#pragma once

#include <Eigen/Core>

namespace watergs {

// Pixel convention (COLMAP's): pixel (col, row) covers [col, col+1) x
// [row, row+1) and its centre is at (col + 0.5, row + 0.5). A camera-frame
// point X projects to u = fx * X.x / X.z + cx, v = fy * X.y / X.z + cy;
// +z looks forward, +y down.
struct RenderCamera {
  // Image size in pixels.
  int width = 0;
  int height = 0;
  // Focal lengths and principal point in pixels.
  double fx = 0, fy = 0, cx = 0, cy = 0;
  // World-to-camera rotation and translation: X_cam = R * X_world + t.
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  // Gaussians whose camera depth is below near_plane are culled.
  double near_plane = 0.01;
  double far_plane = 1000.0;

  // Camera centre in world coordinates, -R^T t.
  Eigen::Vector3d Center() const { return -R.transpose() * t; }
};

}  // namespace watergs
