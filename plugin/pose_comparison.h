// How far a reconstruction's camera poses are from a reference model of the
// same photos, up to the similarity SfM cannot fix (scale, rotation,
// translation). A small mean reprojection error does not show that photos are
// placed right: on repetitive texture the mapper can join two groups of
// photos, each consistent in itself, in a wrong relative pose.
#pragma once

#include <string>

#include "plugin/reconstruction.h"

namespace watergs {

struct PoseComparison {
  // Registered images present in both models (matched by name).
  size_t num_common = 0;
  // Scale of the similarity taking the model onto the reference.
  double scale = 0;
  // Camera centres after the similarity: largest and median distance to the
  // reference's, over the reference's camera spread (RMS distance of its
  // centres from their mean): 0.01 = 1% of the capture's size.
  double max_center_error = 0;
  double median_center_error = 0;
  // Largest angle (degrees) between an image's orientation after the
  // similarity and the reference's.
  double max_rotation_error_deg = 0;
  // Image with the largest centre error.
  std::string worst_image;
};

// Fits the least-squares similarity (Umeyama) on the camera centres of the
// images both models register; fails in one line below 3 common images or
// when the reference's centres all coincide.
PoseComparison ComparePoses(const Reconstruction& model,
                            const Reconstruction& reference);

// "Poses against the reference: 48 common images, ..." (one line).
std::string FormatPoseComparison(const PoseComparison& comparison);

}  // namespace watergs
