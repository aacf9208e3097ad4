// Test helper shared by the module test executables: synthetic cameras.
#pragma once

#include <Eigen/Geometry>

#include "gaussian/camera.h"

namespace watergs {

// A w x h pinhole camera (focal 0.8 w, centred principal point) at `center`
// looking at the origin, world +z up; image +y points up the world (the
// image is upside down: these tests need a rigid camera, not an upright one).
inline RenderCamera LookAtOrigin(const Eigen::Vector3d& center, int w, int h) {
  RenderCamera cam;
  cam.width = w, cam.height = h;
  cam.fx = cam.fy = 0.8 * w;
  cam.cx = 0.5 * w, cam.cy = 0.5 * h;
  const Eigen::Vector3d z = (-center).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d(0, 0, 1).cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  cam.R.row(0) = x;
  cam.R.row(1) = y;
  cam.R.row(2) = z;
  cam.t = -cam.R * center;
  return cam;
}

}  // namespace watergs
