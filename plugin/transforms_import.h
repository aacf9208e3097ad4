// The scenes users download as transforms.json (NeRF-synthetic's
// transforms_{train,val,test}.json, nerfstudio's and Instant-NGP's
// transforms.json) written as a COLMAP workspace, so that train, embed, eval
// and every other command read them through the one Workspace loader:
// images/ (RGBA composited on a chosen background), sparse/0 (text; PINHOLE
// or OpenCV cameras, COLMAP's world-to-camera poses, random initial points
// since these scenes have no SfM points) and test_views.txt (the scene's own
// test split, which Workspace then holds out instead of every 8th view).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "plugin/reconstruction.h"

namespace watergs {

// One frame of a transforms file, as read (before any image is decoded).
struct TransformsFrame {
  // The image file, resolved against the json's folder (NeRF-synthetic's
  // extension-less "./train/r_0" found as r_0.png).
  std::string image_path;
  // The name it gets in the workspace: "<split>/<file name>" for split files,
  // the path relative to the json's folder for a single transforms.json.
  std::string workspace_name;
  // Camera-to-world, camera axes as OpenGL/Blender (x right, y up, z back).
  Eigen::Matrix4d camera_to_world = Eigen::Matrix4d::Identity();
  // COLMAP camera (id unset): PINHOLE, OPENCV, FULL_OPENCV or OPENCV_FISHEYE;
  // width/height 0 when the file does not give them (taken from the image).
  Camera camera;
  // From transforms_test.json.
  bool test = false;
};

// Reads `path`: a transforms.json, or a folder holding transforms.json or
// transforms_train.json (+ transforms_test.json; transforms_val.json is left
// out, as 3DGS trainers leave it). Intrinsics: fl_x/fl_y, else
// camera_angle_x/camera_angle_y (f = w / 2 / tan(angle / 2)), cx/cy
// (default w/2, h/2, COLMAP's pixel convention), k1..k4/p1/p2 by
// camera_model; a frame's own keys override the file's. Every k-th test
// frame is kept (`test_stride`). Throws Error naming the file and the key for
// anything missing, non-finite or not a rotation.
std::vector<TransformsFrame> ReadTransforms(const std::string& path,
                                            int test_stride = 1);

// The COLMAP image (world-to-camera qvec/tvec) of an OpenGL camera-to-world
// matrix: the camera's y and z axes flipped.
Image ImageFromCameraToWorld(const Eigen::Matrix4d& camera_to_world);

// The point nearest every camera's optical axis (least squares), or the mean
// camera centre when the axes are near parallel (a forward-facing capture).
Eigen::Vector3d LookAtCentre(const std::vector<Image>& images);

struct TransformsImportOptions {
  // transforms.json or its folder (ReadTransforms).
  std::string transforms_path;
  // Workspace folder to create; refused if it exists and is not empty.
  std::string output_path;
  // RGBA images composited as rgb * a + background * (1 - a).
  std::array<float, 3> background = {1.f, 1.f, 1.f};
  // Random initial points in a cube around the look-at centre, of half side
  // `points_half_side` times the median camera distance to it (0.32 puts
  // NeRF-synthetic's cameras, 4.03 from the origin, around Inria's 1.3 cube).
  int num_points = 100000;
  double points_half_side = 0.32;
  int test_stride = 1;
  uint64_t seed = 0;
};

struct TransformsImportSummary {
  size_t train_views = 0, test_views = 0, cameras = 0, points = 0;
  size_t composited = 0;  // images that had alpha
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double half_side = 0;
};

// Writes the workspace (into a temporary folder renamed at the end, so an
// error or a kill leaves no half workspace); progress on stderr.
TransformsImportSummary ImportTransforms(
    const TransformsImportOptions& options);

}  // namespace watergs
