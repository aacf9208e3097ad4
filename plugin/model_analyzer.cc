// The summary `colmap model_analyzer` prints, with COLMAP's definitions and
// printf formats so that outputs can be compared line by line.
#include "plugin/model_analyzer.h"

#include <cstdio>

namespace watergs {

ModelSummary AnalyzeModel(const Reconstruction& reconstruction) {
  ModelSummary summary;
  summary.num_cameras = reconstruction.NumCameras();
  summary.num_images = reconstruction.NumImages();
  summary.num_reg_images = reconstruction.NumRegImages();
  summary.num_points3D = reconstruction.NumPoints3D();
  summary.num_observations = reconstruction.ComputeNumObservations();
  summary.mean_track_length = reconstruction.ComputeMeanTrackLength();
  summary.mean_observations_per_image =
      reconstruction.ComputeMeanObservationsPerRegImage();
  summary.mean_reprojection_error =
      reconstruction.ComputeMeanReprojectionError();
  return summary;
}

std::string FormatModelSummary(const ModelSummary& summary) {
  char buffer[1024];
  std::snprintf(buffer, sizeof(buffer),
                "Cameras: %zu\nImages: %zu\nRegistered images: %zu\n"
                "Points: %zu\nObservations: %zu\nMean track length: %f\n"
                "Mean observations per image: %f\n"
                "Mean reprojection error: %fpx\n",
                summary.num_cameras, summary.num_images, summary.num_reg_images,
                summary.num_points3D, summary.num_observations,
                summary.mean_track_length, summary.mean_observations_per_image,
                summary.mean_reprojection_error);
  return buffer;
}

}  // namespace watergs
