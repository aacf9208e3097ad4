// COLMAP's sparse-model data types (Camera, Image, Point3D, Reconstruction),
// mirrored from COLMAP 3.8 so that swapping in colmap::Reconstruction later is
// mechanical: same ids, id types, quaternion convention and statistics.
// Maps are std::unordered_map like COLMAP's, so that iteration (and hence the
// order in written .txt/.bin files) follows COLMAP's for the same insertions.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "plugin/camera_models.h"

namespace watergs {

// COLMAP's id types.
using camera_t = uint32_t;
using image_t = uint32_t;
using point2D_t = uint32_t;
using point3D_t = uint64_t;

constexpr point3D_t kInvalidPoint3DId = std::numeric_limits<point3D_t>::max();

struct Camera {
  // Unique id, referenced by Image::camera_id.
  camera_t camera_id = 0;
  // COLMAP model id 0-10 (camera_models.h).
  int model_id = kInvalidCameraModelId;
  // Image size in pixels.
  uint64_t width = 0;
  uint64_t height = 0;
  // Parameters in COLMAP's order for the model (CameraModelParamsInfo).
  std::vector<double> params;

  // COLMAP's model name, e.g. "PINHOLE".
  std::string ModelName() const { return CameraModelIdToName(model_id); }
  // False only for SIMPLE_PINHOLE and PINHOLE.
  bool HasDistortion() const;
  // Focal lengths (equal for single-focal models) and principal point.
  double FocalLengthX() const { return params[0]; }
  double FocalLengthY() const;
  double PrincipalPointX() const;
  double PrincipalPointY() const;
  // Normalized camera-plane (u, v) -> pixel (x, y), COLMAP's convention.
  Eigen::Vector2d WorldToImage(const Eigen::Vector2d& uv) const;
  // Pixel (x, y) -> normalized camera-plane (u, v).
  Eigen::Vector2d ImageToWorld(const Eigen::Vector2d& xy) const;
};

struct Point2D {
  // Pixel position (COLMAP's convention, pixel centres at +0.5).
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  // The 3D point it observes, or kInvalidPoint3DId.
  point3D_t point3D_id = kInvalidPoint3DId;

  bool HasPoint3D() const { return point3D_id != kInvalidPoint3DId; }
};

struct Image {
  // Unique id, referenced by track elements.
  image_t image_id = 0;
  // File name relative to the image folder.
  std::string name;
  // The camera (intrinsics) it was taken with.
  camera_t camera_id = 0;
  // World-to-camera rotation as a quaternion, w first (COLMAP's qvec).
  Eigen::Vector4d qvec = Eigen::Vector4d(1, 0, 0, 0);
  // World-to-camera translation: X_cam = R(qvec) X_world + tvec.
  Eigen::Vector3d tvec = Eigen::Vector3d::Zero();
  // Keypoints; their index is the point2D_idx of track elements.
  std::vector<Point2D> points2D;

  // Number of points2D that observe a 3D point (COLMAP's NumPoints3D).
  size_t NumPoints3D() const;
  // 3x3 world-to-camera rotation of the normalized qvec.
  Eigen::Matrix3d RotationMatrix() const;
  // Camera centre in world coordinates, -R^T tvec.
  Eigen::Vector3d ProjectionCenter() const;
};

struct TrackElement {
  // The observing image.
  image_t image_id = 0;
  // Index into that image's points2D.
  point2D_t point2D_idx = 0;
};

struct Point3D {
  // World position.
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  // Colour, 0-255 per channel.
  Eigen::Matrix<uint8_t, 3, 1> rgb = Eigen::Matrix<uint8_t, 3, 1>::Zero();
  // Mean reprojection error in pixels; -1 when unknown (COLMAP's default).
  double error = -1;
  // Observations of this point.
  std::vector<TrackElement> track;

  bool HasError() const { return error != -1.0; }
};

// Quaternion divided by its norm; (1, 0, 0, 0) for a zero quaternion, like
// COLMAP's NormalizeQuaternion.
Eigen::Vector4d NormalizeQuaternion(const Eigen::Vector4d& qvec);

class Reconstruction {
 public:
  using CameraMap = std::unordered_map<camera_t, Camera>;
  using ImageMap = std::unordered_map<image_t, Image>;
  using Point3DMap = std::unordered_map<point3D_t, Point3D>;

  const CameraMap& Cameras() const { return cameras_; }
  const ImageMap& Images() const { return images_; }
  const Point3DMap& Points3D() const { return points3D_; }
  // Registered image ids in registration (file) order.
  const std::vector<image_t>& RegImageIds() const { return reg_image_ids_; }

  bool ExistsCamera(camera_t id) const { return cameras_.count(id) > 0; }
  bool ExistsImage(image_t id) const { return images_.count(id) > 0; }
  bool ExistsPoint3D(point3D_t id) const { return points3D_.count(id) > 0; }
  bool IsImageRegistered(image_t id) const;
  const Camera& GetCamera(camera_t id) const { return cameras_.at(id); }
  Camera& GetCamera(camera_t id) { return cameras_.at(id); }
  const Image& GetImage(image_t id) const { return images_.at(id); }
  const Point3D& GetPoint3D(point3D_t id) const { return points3D_.at(id); }

  // Adders return false (and change nothing) if the id already exists.
  bool AddCamera(Camera camera);
  bool AddImage(Image image);
  bool AddPoint3D(point3D_t id, Point3D point3D);
  // Marks an existing image registered (once).
  void RegisterImage(image_t id);

  size_t NumCameras() const { return cameras_.size(); }
  size_t NumImages() const { return images_.size(); }
  size_t NumRegImages() const { return reg_image_ids_.size(); }
  size_t NumPoints3D() const { return points3D_.size(); }

  // COLMAP's statistics (model_analyzer): observations are the points2D of
  // registered images that have a 3D point.
  size_t ComputeNumObservations() const;
  // Observations / points, 0 without points.
  double ComputeMeanTrackLength() const;
  // Observations / registered images, 0 without registered images.
  double ComputeMeanObservationsPerRegImage() const;
  // Mean of Point3D::error over points that have one, 0 if none.
  double ComputeMeanReprojectionError() const;

 private:
  CameraMap cameras_;
  ImageMap images_;
  Point3DMap points3D_;
  std::vector<image_t> reg_image_ids_;
  std::unordered_set<image_t> registered_;
};

}  // namespace watergs
