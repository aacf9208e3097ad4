// ComparePoses: a model equal to the reference up to a similarity reads as
// placed right whatever the similarity; a model in which one group of photos
// was joined to the rest in a wrong relative pose (what sequential matching
// did on the demo scene's repetitive floor, at 0.29 px reprojection error)
// reads as misplaced and names one of those photos.
#include "plugin/pose_comparison.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// An image at `center` looking at the origin, y down (COLMAP's convention).
Image LookingAtOrigin(image_t id, const Eigen::Vector3d& center) {
  const Eigen::Vector3d forward = -center.normalized();
  const Eigen::Vector3d right =
      forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d world_to_camera;
  world_to_camera.row(0) = right;
  world_to_camera.row(1) = down;
  world_to_camera.row(2) = forward;
  const Eigen::Quaterniond q(world_to_camera);
  Image image;
  image.image_id = id;
  image.camera_id = 1;
  image.name = "view_" + std::to_string(100 + id) + ".jpg";
  image.qvec << q.w(), q.x(), q.y(), q.z();
  image.tvec = -world_to_camera * center;
  return image;
}

// Two rings of 12 cameras around the origin, as the demo scene's capture.
Reconstruction TwoRings() {
  Reconstruction r;
  r.AddCamera({1, 1, 480, 360, {400, 400, 240, 180}});
  for (int k = 0; k < 24; ++k) {
    const double angle = 2 * M_PI * (k % 12) / 12.0 + (k < 12 ? 0 : 0.2);
    const Eigen::Vector3d center(4 * std::cos(angle), 4 * std::sin(angle),
                                 k < 12 ? 0.5 : 1.5);
    r.AddImage(LookingAtOrigin(k + 1, center));
    r.RegisterImage(k + 1);
  }
  return r;
}

// `r` moved by x -> s R x + t, each image's pose following.
Reconstruction Moved(const Reconstruction& r, double s,
                     const Eigen::Matrix3d& rotation, const Eigen::Vector3d& t,
                     image_t only_below = 1000) {
  Reconstruction out;
  out.AddCamera(r.Cameras().at(1));
  for (image_t id : r.RegImageIds()) {
    Image image = r.Images().at(id);
    if (id < only_below) {
      const Eigen::Vector3d center =
          s * rotation * image.ProjectionCenter() + t;
      const Eigen::Matrix3d world_to_camera =
          image.RotationMatrix() * rotation.transpose();
      const Eigen::Quaterniond q(world_to_camera);
      image.qvec << q.w(), q.x(), q.y(), q.z();
      image.tvec = -world_to_camera * center;
    }
    out.AddImage(image);
    out.RegisterImage(id);
  }
  return out;
}

TEST(ComparePoses, ASimilarityOfTheReferenceIsPlacedRight) {
  const Reconstruction reference = TwoRings();
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, -2, 0.5).normalized())
          .toRotationMatrix();
  const Reconstruction model =
      Moved(reference, 0.23, rotation, Eigen::Vector3d(3, -1, 7));
  const PoseComparison c = ComparePoses(model, reference);
  EXPECT_EQ(c.num_common, 24u);
  EXPECT_NEAR(c.scale, 1 / 0.23, 1e-9);
  EXPECT_LT(c.max_center_error, 1e-9);
  EXPECT_LT(c.max_rotation_error_deg, 1e-6);
}

TEST(ComparePoses, AGroupJoinedInAWrongPoseIsFound) {
  const Reconstruction reference = TwoRings();
  // The first 9 photos turned half a turn about the vertical axis, each
  // still consistent with the other 8.
  const Eigen::Matrix3d half_turn =
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Reconstruction model =
      Moved(reference, 1, half_turn, Eigen::Vector3d::Zero(), 10);
  const PoseComparison c = ComparePoses(model, reference);
  EXPECT_GT(c.max_center_error, 0.5);
  EXPECT_GT(c.max_rotation_error_deg, 30);
  const int worst = std::stoi(c.worst_image.substr(5, 3)) - 100;
  EXPECT_LT(worst, 10) << c.worst_image;
  EXPECT_NE(FormatPoseComparison(c).find(c.worst_image), std::string::npos);
}

TEST(ComparePoses, RefusesFewerThanThreeCommonImagesAndACollapsedModel) {
  const Reconstruction reference = TwoRings();
  Reconstruction two;
  two.AddCamera(reference.Cameras().at(1));
  for (image_t id : {1, 2}) {
    two.AddImage(reference.Images().at(id));
    two.RegisterImage(id);
  }
  EXPECT_THROW(ComparePoses(two, reference), Error);
  // Every camera of the model at one point: refused, not read as placed right.
  const Reconstruction collapsed =
      Moved(reference, 0, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  EXPECT_THROW(ComparePoses(collapsed, reference), Error);
}

}  // namespace
}  // namespace watergs
