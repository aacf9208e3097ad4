// The summary `colmap model_analyzer` prints for a sparse model.
#pragma once

#include <string>

#include "plugin/reconstruction.h"

namespace watergs {

struct ModelSummary {
  // Cameras, images and registered images (equal when read from files).
  size_t num_cameras = 0;
  size_t num_images = 0;
  size_t num_reg_images = 0;
  // 3D points.
  size_t num_points3D = 0;
  // Keypoints of registered images that observe a 3D point.
  size_t num_observations = 0;
  // Observations / points.
  double mean_track_length = 0;
  // Observations / registered images.
  double mean_observations_per_image = 0;
  // Mean of Point3D::error over points with an error, in pixels.
  double mean_reprojection_error = 0;
};

// Computes the figures with COLMAP's definitions (Reconstruction::Compute*).
ModelSummary AnalyzeModel(const Reconstruction& reconstruction);

// The lines model_analyzer prints, e.g. "Mean track length: 3.250000".
std::string FormatModelSummary(const ModelSummary& summary);

// Median over registered images of (distance to the nearest other camera
// centre) / (median depth of the points the image sees); NaN with fewer than
// two registered images or no point in front. Photos with parallax read
// 0.03-0.3 (LLFF fern and horns 0.03-0.04, the demo's ring 0.29). The demo's
// one ring at one height, registered 24 of 24 at 0.3 px with centres 100%
// off, reads 0.0009: its photos sit in pairs at one pose (the same
// orientation, 0.04-0.09% of the depth apart). Dense video frames (a few cm
// apart at 10-20 m) read like that too.
double MedianNeighbourBaselineToDepth(const Reconstruction& reconstruction);

// Below this, reconstruct warns: most photos sit at the pose of another.
inline constexpr double kCollapsedBaselineToDepth = 0.003;

}  // namespace watergs
