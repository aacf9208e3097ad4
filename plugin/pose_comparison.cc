#include "plugin/pose_comparison.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_map>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {

PoseComparison ComparePoses(const Reconstruction& model,
                            const Reconstruction& reference) {
  std::unordered_map<std::string, const Image*> by_name;
  for (image_t id : reference.RegImageIds()) {
    const Image& image = reference.Images().at(id);
    by_name[image.name] = &image;
  }
  std::vector<std::pair<const Image*, const Image*>> pairs;
  for (image_t id : model.RegImageIds()) {
    const Image& image = model.Images().at(id);
    const auto found = by_name.find(image.name);
    if (found != by_name.end()) pairs.emplace_back(&image, found->second);
  }
  const size_t n = pairs.size();
  if (n < 3) {
    Fail("compare poses: " + std::to_string(n) +
         " images registered in both models (a similarity needs 3)");
  }
  Eigen::Matrix3Xd from(3, n), to(3, n);
  for (size_t k = 0; k < n; ++k) {
    from.col(k) = pairs[k].first->ProjectionCenter();
    to.col(k) = pairs[k].second->ProjectionCenter();
  }
  // RMS distance of the centres from their mean.
  const auto spread_of = [n](const Eigen::Matrix3Xd& centres) {
    const Eigen::Vector3d mean = centres.rowwise().mean();
    return std::sqrt((centres.colwise() - mean).squaredNorm() / double(n));
  };
  const double spread = spread_of(to);
  if (!(spread > 0)) Fail("compare poses: the reference's cameras coincide");
  // A collapsed model has no similarity to the reference: umeyama's scale
  // would be 0 and every error NaN, which compares as "placed right".
  if (!(spread_of(from) > 0))
    Fail("compare poses: the model's cameras coincide");
  const Eigen::Matrix4d similarity = Eigen::umeyama(from, to, true);
  const Eigen::Matrix3d scaled_rotation = similarity.topLeftCorner<3, 3>();
  PoseComparison c;
  c.num_common = n;
  c.scale = std::cbrt(scaled_rotation.determinant());
  const Eigen::Matrix3d rotation = scaled_rotation / c.scale;
  std::vector<double> errors(n);
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d moved =
        scaled_rotation * from.col(k) + similarity.topRightCorner<3, 1>();
    errors[k] = (moved - to.col(k)).norm() / spread;
    if (errors[k] > c.max_center_error) {
      c.max_center_error = errors[k];
      c.worst_image = pairs[k].first->name;
    }
    // World-to-camera rotation in the reference's frame: R_model R^T.
    const Eigen::Matrix3d moved_rotation =
        pairs[k].first->RotationMatrix() * rotation.transpose();
    const Eigen::AngleAxisd difference(
        moved_rotation * pairs[k].second->RotationMatrix().transpose());
    c.max_rotation_error_deg = std::max(
        c.max_rotation_error_deg, std::abs(difference.angle()) * 180 / M_PI);
  }
  std::nth_element(errors.begin(), errors.begin() + n / 2, errors.end());
  c.median_center_error = errors[n / 2];
  return c;
}

std::string FormatPoseComparison(const PoseComparison& c) {
  char line[512];
  std::snprintf(line, sizeof(line),
                "Poses against the reference: %zu common images, camera "
                "centres off by median %.2f%% and at most %.2f%% of the "
                "capture's size (%s), orientations at most %.2f deg, scale "
                "%.4g\n",
                c.num_common, 100 * c.median_center_error,
                100 * c.max_center_error, c.worst_image.c_str(),
                c.max_rotation_error_deg, c.scale);
  return line;
}

}  // namespace watergs
