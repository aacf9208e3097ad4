// SH colour: the hand-written backward against ceres::Jet of the template,
// and the basis constants against orthonormality on the sphere.
#include "gaussian/sh.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/gaussian_model.h"

namespace watergs {
namespace {

constexpr int kRest = 45;                // 15 coefficients x rgb.
constexpr int kJetDims = 3 + 3 + kRest;  // dir, dc, rest.
using JetT = ceres::Jet<double, kJetDims>;

TEST(Sh, BackwardMatchesJet) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int degree = 0; degree <= 3; ++degree) {
    for (int trial = 0; trial < 20; ++trial) {
      float dc[3], rest[kRest];
      for (float& v : dc) v = static_cast<float>(u(rng));
      for (float& v : rest) v = static_cast<float>(u(rng));
      const double dir[3] = {3 * u(rng), 3 * u(rng), 3 * u(rng)};
      const double grad_rgb[3] = {u(rng), u(rng), u(rng)};
      JetT jdir[3], jdc[3], jrest[kRest], jrgb[3];
      for (int k = 0; k < 3; ++k) jdir[k] = JetT(dir[k], k);
      for (int k = 0; k < 3; ++k) jdc[k] = JetT(dc[k], 3 + k);
      for (int k = 0; k < kRest; ++k) jrest[k] = JetT(rest[k], 6 + k);
      ShColorUnclamped(degree, jdc, jrest, jdir, jrgb);
      Eigen::Matrix<double, kJetDims, 1> expected =
          Eigen::Matrix<double, kJetDims, 1>::Zero();
      for (int ch = 0; ch < 3; ++ch) expected += grad_rgb[ch] * jrgb[ch].v;
      float grad_dc[3] = {0, 0, 0}, grad_rest[kRest] = {};
      double grad_dir[3] = {0, 0, 0};
      ShColorBackward(degree, dc, rest, dir, grad_rgb, grad_dc, grad_rest,
                      grad_dir);
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(grad_dir[k], expected[k], 1e-10) << degree;
        EXPECT_NEAR(grad_dc[k], expected[3 + k], 1e-6) << degree;
      }
      for (int k = 0; k < kRest; ++k) {
        EXPECT_NEAR(grad_rest[k], expected[6 + k], 1e-6) << degree << " " << k;
      }
    }
  }
}

TEST(Sh, BasisIsOrthonormalOnTheSphere) {
  // Fibonacci-sphere quadrature: sum Y_i Y_j * 4 pi / n -> delta_ij.
  constexpr int n = 40000;
  double gram[16][16] = {};
  const double golden = M_PI * (3 - std::sqrt(5.0));
  for (int k = 0; k < n; ++k) {
    const double z = 1 - (2 * k + 1.0) / n;
    const double r = std::sqrt(1 - z * z);
    const double x = r * std::cos(golden * k), y = r * std::sin(golden * k);
    double b[16];
    ShBasis(3, x, y, z, b);
    for (int i = 0; i < 16; ++i) {
      for (int j = 0; j < 16; ++j) gram[i][j] += b[i] * b[j] * 4 * M_PI / n;
    }
  }
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 16; ++j) {
      EXPECT_NEAR(gram[i][j], i == j ? 1.0 : 0.0, 1e-3) << i << "," << j;
    }
  }
}

TEST(Sh, DegreeZeroIsDcColourPlusHalf) {
  const float dc[3] = {RgbToShDc(0.2f), RgbToShDc(0.7f), RgbToShDc(1.0f)};
  const float rest[kRest] = {};
  const double dir[3] = {0.3, -2, 1};
  double rgb[3];
  ShColorUnclamped(0, dc, rest, dir, rgb);
  EXPECT_NEAR(rgb[0], 0.2, 1e-6);
  EXPECT_NEAR(rgb[1], 0.7, 1e-6);
  EXPECT_NEAR(rgb[2], 1.0, 1e-6);
}

TEST(Sh, ZeroDirectionStaysFinite) {
  float dc[3] = {1, 1, 1}, rest[kRest];
  for (float& v : rest) v = 1;
  const double dir[3] = {0, 0, 0}, grad_rgb[3] = {1, 1, 1};
  double rgb[3], grad_dir[3] = {0, 0, 0};
  ShColorUnclamped(3, dc, rest, dir, rgb);
  float grad_dc[3] = {}, grad_rest[kRest] = {};
  ShColorBackward(3, dc, rest, dir, grad_rgb, grad_dc, grad_rest, grad_dir);
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(std::isfinite(rgb[k]));
    EXPECT_TRUE(std::isfinite(grad_dir[k]));
  }
}

}  // namespace
}  // namespace watergs
