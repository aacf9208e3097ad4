// MedianNeighbourBaselineToDepth: the synthetic ring's figure from its
// geometry, and a collapsed copy of it (every centre pulled to within 1e-4 of
// one spot, the same rotations) far below kCollapsedBaselineToDepth.
#include "plugin/model_analyzer.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

// `model` with every camera centre moved to mean + factor * (centre - mean).
Reconstruction PullCentres(const Reconstruction& model, double factor) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const image_t id : model.RegImageIds()) {
    mean += model.GetImage(id).ProjectionCenter();
  }
  mean /= double(model.NumRegImages());
  Reconstruction pulled;
  for (const auto& [id, camera] : model.Cameras()) pulled.AddCamera(camera);
  for (const image_t id : model.RegImageIds()) {
    Image image = model.GetImage(id);
    const Eigen::Vector3d centre =
        mean + factor * (image.ProjectionCenter() - mean);
    image.tvec = -image.RotationMatrix() * centre;
    pulled.AddImage(image);
    pulled.RegisterImage(id);
  }
  for (const auto& [id, point] : model.Points3D()) pulled.AddPoint3D(id, point);
  return pulled;
}

TEST(MedianNeighbourBaselineToDepth, ReadsTheRingsSpacingAndFlagsACollapse) {
  testing::SyntheticModelOptions options;
  options.num_images = 12;
  const Reconstruction ring = testing::MakeSyntheticReconstruction(options);
  // 12 cameras on a ring of radius 4 looking at points around the origin:
  // neighbours 2 * 4 * sin(15 deg) = 2.07 apart at a depth of about 4.
  const double ratio = MedianNeighbourBaselineToDepth(ring);
  EXPECT_GT(ratio, 0.35);
  EXPECT_LT(ratio, 0.75);
  EXPECT_GT(ratio, 100 * kCollapsedBaselineToDepth);
  const Reconstruction collapsed = PullCentres(ring, 1e-4);
  EXPECT_LT(MedianNeighbourBaselineToDepth(collapsed),
            kCollapsedBaselineToDepth);
  Reconstruction lone;
  EXPECT_TRUE(std::isnan(MedianNeighbourBaselineToDepth(lone)));
}

}  // namespace
}  // namespace watergs
