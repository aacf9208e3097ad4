#include "gaussian/depth_render.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "gaussian/rasterizer.h"
#include "tests/common/flat_gaussians.h"

namespace watergs {
namespace {

// Flat, opaque Gaussians on a grid over the plane n . X = c (world = camera
// frame), spanning [-half, half]^2 in x and y: a surface whose depth along
// each pixel's ray is known in closed form.
GaussianModel PlaneOfGaussians(const Eigen::Vector3d& n, double c, double half,
                               double spacing, float opacity_logit = 4.f) {
  GaussianModel m;
  m.sh_degree = 0;
  const int steps = int(2 * half / spacing) + 1;
  for (int i = 0; i < steps; ++i) {
    for (int j = 0; j < steps; ++j) {
      const double x = -half + i * spacing, y = -half + j * spacing;
      const double z = (c - n.x() * x - n.y() * y) / n.z();
      // In-plane sigma 0.8 spacing, 1% of it along the normal.
      AppendFlatGaussian(&m, {x, y, z}, n, 0.8 * spacing, 0.008 * spacing,
                         opacity_logit, {0.5f, 0.5f, 0.5f});
    }
  }
  return m;
}

RenderCamera Camera() {
  RenderCamera camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 60;
  camera.cx = 32;
  camera.cy = 24;
  return camera;
}

// A tilted plane's depth, pixel by pixel, against the ray-plane intersection.
// Its Gaussians are translucent (alpha 0.12 at their centres, the plane
// covering about half of each pixel): the depth is a weighted mean, not a sum.
TEST(RenderDepth, FollowsATiltedTranslucentPlaneAlongEveryRay) {
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 1).normalized();
  const double c = 4 * n.z();  // depth 4 on the optical axis
  const GaussianModel plane = PlaneOfGaussians(n, c, 3.0, 0.05, -2.f);
  const RenderCamera camera = Camera();
  auto rasterizer = MakeCpuRasterizer();
  const std::vector<float> depth =
      RenderDepth(*rasterizer, plane, camera, /*min_coverage=*/0.1);
  ASSERT_EQ(depth.size(), size_t(camera.width * camera.height));
  double worst = 0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray((u + 0.5 - camera.cx) / camera.fx,
                                (v + 0.5 - camera.cy) / camera.fy, 1);
      const double truth = c / n.dot(ray);
      const float d = depth[size_t(v) * camera.width + u];
      ASSERT_TRUE(std::isfinite(d)) << "pixel " << u << "," << v;
      worst = std::max(worst, std::abs(d - truth) / truth);
    }
  }
  EXPECT_LT(worst, 0.01);
}

// Where nothing covers a pixel its depth is NaN; a nearer surface hides a
// farther one.
TEST(RenderDepth, NaNOnTheBackgroundAndTheNearestSurfaceInFront) {
  const RenderCamera camera = Camera();
  GaussianModel scene =
      PlaneOfGaussians(Eigen::Vector3d::UnitZ(), 5, 1.0, 0.05);
  // A nearer square at depth 3 over the plane's centre.
  const GaussianModel near =
      PlaneOfGaussians(Eigen::Vector3d::UnitZ(), 3, 0.3, 0.05);
  for (size_t i = 0; i < near.size(); ++i) scene.AppendFrom(near, i);
  auto rasterizer = MakeCpuRasterizer();
  const std::vector<float> depth = RenderDepth(*rasterizer, scene, camera);
  auto at = [&](int u, int v) { return depth[size_t(v) * camera.width + u]; };
  EXPECT_NEAR(at(32, 24), 3.0, 0.03);  // the near square (0.3 * 60 / 3 = 6 px)
  EXPECT_NEAR(at(32, 24 + 12), 5.0,
              0.05);  // the plane around it (12 px = 1 unit at 5)
  EXPECT_TRUE(
      std::isnan(at(0, 0)));  // beyond the plane's edge (1 unit = 12 px)
  EXPECT_TRUE(std::isnan(at(63, 47)));
}

// A model entirely behind the camera: every pixel NaN, nothing divided by 0.
TEST(RenderDepth, NothingInFrontIsAllNaN) {
  const GaussianModel behind =
      PlaneOfGaussians(Eigen::Vector3d::UnitZ(), -4, 1.0, 0.1);
  auto rasterizer = MakeCpuRasterizer();
  for (float d : RenderDepth(*rasterizer, behind, Camera())) {
    EXPECT_TRUE(std::isnan(d));
  }
}

}  // namespace
}  // namespace watergs
