// SH colour: the hand-written backward against ceres::Jet of the template,
// the basis constants against orthonormality on the sphere, and the whole
// convention (basis signs and order, PLY coefficient layout, view direction)
// against colours computed here from the textbook definition.
#include "gaussian/sh.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/gaussian_model.h"
#include "tests/common/look_at.h"

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

// Real spherical harmonic of degree l and order m (-l..l) at unit (x, y, z),
// from its definition and independently of sh.h: with theta measured from +z
// and phi = atan2(y, x),
//   Y_l^0  = K_l^0 P_l^0(cos theta)
//   Y_l^m  = sqrt(2) K_l^m  cos(m phi)   P_l^m(cos theta)    (m > 0)
//   Y_l^-m = sqrt(2) K_l^m  sin(m phi)   P_l^m(cos theta)    (m > 0)
//   K_l^m  = sqrt((2l + 1) / (4 pi) (l - m)! / (l + m)!)
// where P_l^m carries the Condon-Shortley phase (-1)^m, the convention of
// the Inria code (sh_utils.py: Y_1 = -C1 y, C1 z, -C1 x). std::assoc_legendre
// leaves the phase out, so it is applied here.
double RealSh(int l, int m, double x, double y, double z) {
  const int am = std::abs(m);
  const double theta = std::acos(std::clamp(z, -1.0, 1.0));
  const double phi = std::atan2(y, x);
  const double legendre =
      (am % 2 ? -1.0 : 1.0) * std::assoc_legendre(l, am, std::cos(theta));
  const double k = std::sqrt((2 * l + 1) / (4 * M_PI) *
                             std::tgamma(l - am + 1) / std::tgamma(l + am + 1));
  if (m == 0) return k * legendre;
  const double angular = m > 0 ? std::cos(am * phi) : std::sin(am * phi);
  return std::sqrt(2.0) * k * angular * legendre;
}

// One Gaussian written as Inria's PLY writes it (binary little endian,
// x y z nx ny nz f_dc_0..2 f_rest_0..44 opacity scale_0..2 rot_0..3, f_rest
// channel-major: f_rest_{15 c + j} is coefficient j + 1 of channel c), read
// back with ReadPly and rendered head-on from several sides by the CPU
// rasterizer. The pixel under the Gaussian's centre is alpha times its
// colour, 0.5 + sum over l, m of Y_l^m(d) times its coefficient, d the unit
// vector from the camera to the Gaussian; both are computed here from the
// record. A sign, an order or a channel-major/coefficient-major mix-up in
// sh.h or ply_io.cc (which orthonormality cannot see) moves it by hundredths,
// far beyond the float rounding (~1e-7) that the 2e-5 tolerance allows for.
TEST(Sh, RenderedColourFollowsTheRealShDefinitionAndInriasPlyLayout) {
  float f_dc[3] = {0.3f, -0.2f, 0.1f}, f_rest[45];
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(-0.08f, 0.08f);
  for (float& v : f_rest) v = u(rng);
  const float opacity_logit = std::log(0.8f / 0.2f);
  std::vector<std::string> names = {"x", "y", "z", "nx", "ny", "nz"};
  std::vector<float> record = {0, 0, 0, 0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    names.push_back("f_dc_" + std::to_string(c));
    record.push_back(f_dc[c]);
  }
  for (int j = 0; j < 45; ++j) {
    names.push_back("f_rest_" + std::to_string(j));
    record.push_back(f_rest[j]);
  }
  names.push_back("opacity");
  record.push_back(opacity_logit);
  for (int a = 0; a < 3; ++a) {
    names.push_back("scale_" + std::to_string(a));
    record.push_back(std::log(0.3f));
  }
  for (int a = 0; a < 4; ++a) {
    names.push_back("rot_" + std::to_string(a));
    record.push_back(a == 0 ? 1.f : 0.f);
  }
  const std::string path =
      (std::filesystem::temp_directory_path() /
       ("watergs_sh_convention_" + std::to_string(::getpid()) + ".ply"))
          .string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex 1\n";
    for (const std::string& name : names)
      out << "property float " << name << "\n";
    out << "end_header\n";
    out.write(reinterpret_cast<const char*>(record.data()),
              record.size() * sizeof(float));
  }
  const GaussianModel model = ReadPly(path).model;
  std::filesystem::remove(path);
  ASSERT_EQ(model.size(), 1u);
  ASSERT_EQ(model.sh_degree, 3);

  auto rasterizer = MakeCpuRasterizer();
  const double alpha = 1 / (1 + std::exp(-double(opacity_logit)));
  for (const Eigen::Vector3d& center :
       {Eigen::Vector3d(3, 0, 0.5), Eigen::Vector3d(-1, 2.5, -1.2),
        Eigen::Vector3d(0.3, -2, 2.2), Eigen::Vector3d(-2, -1.5, 0.4),
        Eigen::Vector3d(1.5, 1.5, -2)}) {
    // Odd size: the centre pixel's centre (16.5, 16.5) is the principal
    // point, where the Gaussian at the origin projects.
    const RenderCamera camera = LookAtOrigin(center, 33, 33);
    ImageRGB image;
    rasterizer->Forward(model, camera, RenderOptions{}, &image, nullptr);
    const Eigen::Vector3d d = -center.normalized();
    for (int c = 0; c < 3; ++c) {
      double colour = 0.5 + RealSh(0, 0, d.x(), d.y(), d.z()) * f_dc[c];
      for (int l = 1; l <= 3; ++l) {
        for (int m = -l; m <= l; ++m) {
          const int j = l * l + l + m - 1;  // coefficient index - 1
          colour += RealSh(l, m, d.x(), d.y(), d.z()) * f_rest[15 * c + j];
        }
      }
      ASSERT_GT(colour, 0.05) << "keep clear of the clamp at 0";
      EXPECT_NEAR(image.At(16, 16)[c], alpha * colour, 2e-5)
          << "camera at " << center.transpose() << ", channel " << c;
    }
  }
}

}  // namespace
}  // namespace watergs
