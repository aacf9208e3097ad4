// The summary `colmap model_analyzer` prints, with COLMAP's definitions and
// printf formats so that outputs can be compared line by line.
#include "plugin/model_analyzer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

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

namespace {

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2,
                   values.end());
  return values[values.size() / 2];
}

}  // namespace

double MedianNeighbourBaselineToDepth(const Reconstruction& reconstruction) {
  const std::vector<image_t>& ids = reconstruction.RegImageIds();
  std::vector<Eigen::Vector3d> centres;
  for (const image_t id : ids) {
    centres.push_back(reconstruction.GetImage(id).ProjectionCenter());
  }
  std::vector<double> ratios;
  for (size_t k = 0; k < ids.size(); ++k) {
    const Image& image = reconstruction.GetImage(ids[k]);
    const Eigen::Matrix3d rotation = image.RotationMatrix();
    std::vector<double> depths;
    for (const Point2D& p : image.points2D) {
      if (!p.HasPoint3D() || !reconstruction.ExistsPoint3D(p.point3D_id)) {
        continue;
      }
      const double z =
          (rotation * reconstruction.GetPoint3D(p.point3D_id).xyz + image.tvec)
              .z();
      if (z > 0) depths.push_back(z);
    }
    double nearest = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < ids.size(); ++j) {
      if (j != k) nearest = std::min(nearest, (centres[j] - centres[k]).norm());
    }
    if (!depths.empty() && std::isfinite(nearest)) {
      ratios.push_back(nearest / Median(std::move(depths)));
    }
  }
  if (ratios.empty()) return std::numeric_limits<double>::quiet_NaN();
  return Median(std::move(ratios));
}

}  // namespace watergs
