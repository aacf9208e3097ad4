// COLMAP's sparse-model data types: camera helpers, quaternions and the
// statistics `colmap model_analyzer` prints.
#include "plugin/reconstruction.h"

#include <Eigen/Geometry>
#include <algorithm>

namespace watergs {

bool Camera::HasDistortion() const {
  return model_id != SimplePinholeCameraModel::kModelId &&
         model_id != PinholeCameraModel::kModelId;
}

double Camera::FocalLengthY() const {
  return CameraModelHasSingleFocalLength(model_id) ? params[0] : params[1];
}

double Camera::PrincipalPointX() const {
  return CameraModelHasSingleFocalLength(model_id) ? params[1] : params[2];
}

double Camera::PrincipalPointY() const {
  return CameraModelHasSingleFocalLength(model_id) ? params[2] : params[3];
}

Eigen::Vector2d Camera::WorldToImage(const Eigen::Vector2d& uv) const {
  Eigen::Vector2d xy;
  CameraModelWorldToImage(model_id, params, uv(0), uv(1), &xy(0), &xy(1));
  return xy;
}

Eigen::Vector2d Camera::ImageToWorld(const Eigen::Vector2d& xy) const {
  Eigen::Vector2d uv;
  CameraModelImageToWorld(model_id, params, xy(0), xy(1), &uv(0), &uv(1));
  return uv;
}

size_t Image::NumPoints3D() const {
  return std::count_if(points2D.begin(), points2D.end(),
                       [](const Point2D& p) { return p.HasPoint3D(); });
}

Eigen::Matrix3d Image::RotationMatrix() const {
  const Eigen::Vector4d q = NormalizeQuaternion(qvec);
  return Eigen::Quaterniond(q(0), q(1), q(2), q(3)).toRotationMatrix();
}

Eigen::Vector3d Image::ProjectionCenter() const {
  return -RotationMatrix().transpose() * tvec;
}

Eigen::Vector4d NormalizeQuaternion(const Eigen::Vector4d& qvec) {
  const double norm = qvec.norm();
  if (norm == 0) return Eigen::Vector4d(1, 0, 0, 0);
  return qvec / norm;
}

bool Reconstruction::IsImageRegistered(image_t id) const {
  return registered_.count(id) > 0;
}

bool Reconstruction::AddCamera(Camera camera) {
  const camera_t id = camera.camera_id;
  return cameras_.emplace(id, std::move(camera)).second;
}

bool Reconstruction::AddImage(Image image) {
  const image_t id = image.image_id;
  return images_.emplace(id, std::move(image)).second;
}

bool Reconstruction::AddPoint3D(point3D_t id, Point3D point3D) {
  return points3D_.emplace(id, std::move(point3D)).second;
}

void Reconstruction::RegisterImage(image_t id) {
  if (ExistsImage(id) && registered_.insert(id).second) {
    reg_image_ids_.push_back(id);
  }
}

size_t Reconstruction::ComputeNumObservations() const {
  size_t num_observations = 0;
  for (const image_t id : reg_image_ids_) {
    num_observations += images_.at(id).NumPoints3D();
  }
  return num_observations;
}

double Reconstruction::ComputeMeanTrackLength() const {
  if (points3D_.empty()) return 0.0;
  return ComputeNumObservations() / static_cast<double>(points3D_.size());
}

double Reconstruction::ComputeMeanObservationsPerRegImage() const {
  if (reg_image_ids_.empty()) return 0.0;
  return ComputeNumObservations() / static_cast<double>(reg_image_ids_.size());
}

double Reconstruction::ComputeMeanReprojectionError() const {
  double error_sum = 0.0;
  size_t num_valid_errors = 0;
  for (const auto& [id, point3D] : points3D_) {
    if (!point3D.HasError()) continue;
    error_sum += point3D.error;
    ++num_valid_errors;
  }
  return num_valid_errors == 0 ? 0.0 : error_sum / num_valid_errors;
}

}  // namespace watergs
