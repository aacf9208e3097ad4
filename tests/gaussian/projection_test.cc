// EWA projection: the hand-written backward against ceres::Jet of the
// templates (inside and outside Inria's 1.3 x FOV clamp, unnormalised and
// zero quaternions, clamped log-scales), and the forward against Eigen.
#include "gaussian/projection.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "gaussian/tile_binning.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using JetT = ceres::Jet<double, 10>;  // mean (3), log-scale (3), quat (4).

// Compares ProjectBackward with the Jet derivative of ProjectGaussian for
// random upstream gradients; returns false if the conic is undefined.
void ExpectBackwardMatchesJet(const ProjectionCamera& cam, const float* mean,
                              const float* log_scale, const float* quat,
                              std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  JetT jm[3], jls[3], jq[4], jmean2d[2], jconic[3];
  for (int k = 0; k < 3; ++k) jm[k] = JetT(mean[k], k);
  for (int k = 0; k < 3; ++k) jls[k] = JetT(log_scale[k], 3 + k);
  for (int k = 0; k < 4; ++k) jq[k] = JetT(quat[k], 6 + k);
  ASSERT_TRUE(ProjectGaussian(cam, jm, jls, jq, jmean2d, jconic));
  const double g2[2] = {u(*rng), u(*rng)};
  // Conic entries are ~1/variance: scale so every term matters.
  const double gc[3] = {10 * u(*rng), 10 * u(*rng), 10 * u(*rng)};
  Eigen::Matrix<double, 10, 1> expected =
      g2[0] * jmean2d[0].v + g2[1] * jmean2d[1].v + gc[0] * jconic[0].v +
      gc[1] * jconic[1].v + gc[2] * jconic[2].v;
  double gm[3] = {0, 0, 0}, gls[3] = {0, 0, 0}, gq[4] = {0, 0, 0, 0};
  ProjectBackward(cam, mean, log_scale, quat, g2, gc, gm, gls, gq);
  const double got[10] = {gm[0],  gm[1], gm[2], gls[0], gls[1],
                          gls[2], gq[0], gq[1], gq[2],  gq[3]};
  const double scale = expected.cwiseAbs().maxCoeff() + 1e-12;
  for (int k = 0; k < 10; ++k) {
    EXPECT_NEAR(got[k], expected[k], 1e-9 * scale) << "component " << k;
  }
}

TEST(Projection, BackwardMatchesJetOnRandomGaussians) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1);
  for (unsigned seed = 0; seed < 5; ++seed) {
    const RenderCamera rc = testing::RandomCamera(80, 60, seed);
    const ProjectionCamera cam = MakeProjectionCamera(rc);
    testing::SceneSpec spec;
    spec.count = 30;
    spec.margin = 60;  // Some means far outside: the clamp branch.
    const GaussianModel m = testing::RandomScene(rc, spec, seed);
    for (size_t i = 0; i < m.size(); ++i) {
      float quat[4];
      for (int k = 0; k < 4; ++k) quat[k] = m.quats[4 * i + k] * 3.0f;
      ExpectBackwardMatchesJet(cam, &m.means[3 * i], &m.log_scales[3 * i], quat,
                               &rng);
    }
  }
}

TEST(Projection, BackwardMatchesJetWhenFrustumClampBinds) {
  std::mt19937 rng(4);
  const RenderCamera rc = testing::RandomCamera(64, 48, 1);
  const ProjectionCamera cam = MakeProjectionCamera(rc);
  // Camera-frame points with |x/z| and |y/z| beyond 1.3 tan(half FOV).
  const double lim = 1.3 * cam.tan_fovx;
  const Eigen::Vector3d points[] = {{2.0 * lim * 3, 0.1, 3},
                                    {-1.5 * lim * 2, -3.0 * lim * 2, 2},
                                    {0.2, 2.5 * lim * 4, 4}};
  for (const Eigen::Vector3d& xc : points) {
    const Eigen::Vector3d xw = rc.R.transpose() * (xc - rc.t);
    const float mean[3] = {float(xw[0]), float(xw[1]), float(xw[2])};
    const float ls[3] = {-1.0f, -2.0f, -1.5f};
    const float quat[4] = {0.3f, -0.5f, 0.8f, 0.1f};
    ExpectBackwardMatchesJet(cam, mean, ls, quat, &rng);
  }
}

TEST(Projection, ZeroQuaternionAndClampedScalesHaveFiniteGradients) {
  std::mt19937 rng(5);
  const RenderCamera rc = testing::RandomCamera(64, 48, 2);
  const ProjectionCamera cam = MakeProjectionCamera(rc);
  const Eigen::Vector3d xw =
      rc.R.transpose() * (Eigen::Vector3d(0.1, 0, 3) - rc.t);
  const float mean[3] = {float(xw[0]), float(xw[1]), float(xw[2])};
  const float zero_quat[4] = {0, 0, 0, 0};
  const float ls[3] = {19, -100, 25};  // Free, clamped below and above.
  ExpectBackwardMatchesJet(cam, mean, ls, zero_quat, &rng);
  double gm[3] = {}, gls[3] = {}, gq[4] = {};
  const double g2[2] = {1, 1}, gc[3] = {1, 1, 1};
  ProjectBackward(cam, mean, ls, zero_quat, g2, gc, gm, gls, gq);
  for (double v : gq) EXPECT_EQ(v, 0.0);
  EXPECT_EQ(gls[1], 0.0);
  EXPECT_EQ(gls[2], 0.0);
  EXPECT_NE(gls[0], 0.0);
}

TEST(Projection, Covariance3dHasScaleEigenvaluesAlongRotationAxes) {
  std::mt19937 rng(6);
  std::normal_distribution<double> n(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const double q[4] = {n(rng), n(rng), n(rng), n(rng)};
    const double ls[3] = {n(rng), n(rng), n(rng)};
    double cov[6];
    Covariance3d(ls, q, cov);
    Eigen::Matrix3d sigma;
    sigma << cov[0], cov[1], cov[2], cov[1], cov[3], cov[4], cov[2], cov[4],
        cov[5];
    const Eigen::Matrix3d rot =
        Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().matrix();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d axis = rot.col(k);
      const Eigen::Vector3d image = sigma * axis;
      const Eigen::Vector3d want = std::exp(2 * ls[k]) * axis;
      EXPECT_LT((image - want).norm(), 1e-12 * (1 + want.norm()));
    }
  }
}

TEST(Projection, ForwardMatchesPinholeAndCulls) {
  const RenderCamera rc = testing::RandomCamera(64, 48, 7);
  const ProjectionCamera cam = MakeProjectionCamera(rc);
  auto world = [&](double x, double y, double z) {
    const Eigen::Vector3d w =
        rc.R.transpose() * (Eigen::Vector3d(x, y, z) - rc.t);
    return std::array<float, 3>{float(w[0]), float(w[1]), float(w[2])};
  };
  const float ls[3] = {-3, -3, -3}, quat[4] = {1, 0, 0, 0};
  ProjectedGaussian p;
  const auto in_front = world(0.2, -0.1, 2.0);
  ASSERT_TRUE(ProjectForward(cam, in_front.data(), ls, quat, &p));
  // The float mean's camera point projects by the pinhole model.
  Eigen::Vector3d xc =
      rc.R * Eigen::Vector3d(in_front[0], in_front[1], in_front[2]) + rc.t;
  EXPECT_NEAR(p.mean2d[0], rc.fx * xc.x() / xc.z() + rc.cx, 1e-9);
  EXPECT_NEAR(p.mean2d[1], rc.fy * xc.y() / xc.z() + rc.cy, 1e-9);
  EXPECT_NEAR(p.depth, xc.z(), 1e-12);
  EXPECT_GT(p.radius, 0);
  const auto behind = world(0.2, -0.1, -2.0);
  EXPECT_FALSE(ProjectForward(cam, behind.data(), ls, quat, &p));
  const auto at_near = world(0.0, 0.0, 0.5 * rc.near_plane);
  EXPECT_FALSE(ProjectForward(cam, at_near.data(), ls, quat, &p));
  const auto off_screen = world(50.0, 0.0, 2.0);
  EXPECT_FALSE(ProjectForward(cam, off_screen.data(), ls, quat, &p));
}

TEST(Projection, MayTouchTilesNeverRejectsWhatProjectionKeeps) {
  int kept = 0, rejected = 0;
  for (unsigned seed = 0; seed < 4; ++seed) {
    const RenderCamera rc = testing::RandomCamera(200, 150, seed);
    const ProjectionCamera cam = MakeProjectionCamera(rc);
    testing::SceneSpec spec;
    spec.count = 400;
    spec.margin = 150;
    spec.min_scale = 0.001, spec.max_scale = 2.0;
    const GaussianModel m = testing::RandomScene(rc, spec, 40 + seed);
    const TileRange ranges[] = {{0, 0, 13, 10}, {3, 2, 5, 4}, {12, 9, 13, 10}};
    for (const TileRange& range : ranges) {
      for (size_t i = 0; i < m.size(); ++i) {
        ProjectedGaussian p;
        const bool hits =
            ProjectForward(cam, &m.means[3 * i], &m.log_scales[3 * i],
                           &m.quats[4 * i], &p) &&
            !Intersect(p.tiles, range).empty();
        const bool may =
            MayTouchTiles(cam, &m.means[3 * i], &m.log_scales[3 * i], range);
        if (hits) {
          EXPECT_TRUE(may) << i;
        }
        kept += hits;
        rejected += !may;
      }
    }
  }
  // Both outcomes occur, so the test exercises the bound.
  EXPECT_GT(kept, 100);
  EXPECT_GT(rejected, 100);
}

}  // namespace
}  // namespace watergs
