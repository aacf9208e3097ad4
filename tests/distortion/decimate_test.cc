// Tests of decimation by moment-matched neighbour merges: a merge matches
// the mixture's mean and covariance (checked against samples drawn from the
// pair), counts, the scene's mass-weighted centre, hard cases, refusals.
#include "distortion/decimate.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <set>

#include "distortion/file_attacks.h"
#include "gaussian/util/error.h"
#include "tests/common/random_model.h"

namespace watergs {
namespace {

GaussianModel Scene(size_t n, uint64_t seed) { return RandomModel(n, 2, seed); }

Eigen::Matrix3d CovarianceOf(const GaussianModel& m, size_t i) {
  const float* q = &m.quats[4 * i];
  const Eigen::Matrix3d r = Eigen::Quaterniond(q[0], q[1], q[2], q[3])
                                .normalized()
                                .toRotationMatrix();
  Eigen::Vector3d s;
  for (int k = 0; k < 3; ++k) s[k] = std::exp(m.log_scales[3 * i + k]);
  return r * s.cwiseProduct(s).asDiagonal() * r.transpose();
}

double Mass(const GaussianModel& m, size_t i) {
  return OpacityLogitToAlpha(m.opacity_logits[i]) *
         std::exp(double(m.log_scales[3 * i]) + m.log_scales[3 * i + 1] +
                  m.log_scales[3 * i + 2]);
}

void ExpectFinite(const GaussianModel& m) {
  for (const std::vector<float>* a :
       {&m.means, &m.log_scales, &m.quats, &m.opacity_logits, &m.sh_dc,
        &m.sh_rest}) {
    for (float v : *a) ASSERT_TRUE(std::isfinite(v));
  }
}

TEST(Decimate, MergeMatchesTheMixtureSampled) {
  // Two overlapping, differently shaped and weighted Gaussians: draw from
  // the mixture with probabilities opacity * volume and compare the merged
  // Gaussian's mean and covariance with the samples'.
  GaussianModel m = Scene(2, 5);
  m.log_scales = {-1.0f, -2.0f, -1.5f, -1.8f, -1.2f, -2.2f};
  m.means = {0.1f, -0.2f, 0.3f, 0.5f, 0.1f, -0.2f};
  m.opacity_logits = {1.0f, -0.5f};
  GaussianModel out;
  out.sh_degree = m.sh_degree;
  out.Resize(1);
  MergeGaussianPair(m, 0, 1, &out, 0);
  ExpectFinite(out);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0, 1);
  const double p0 = Mass(m, 0) / (Mass(m, 0) + Mass(m, 1));
  std::bernoulli_distribution pick_first(p0);
  const Eigen::LLT<Eigen::Matrix3d> l0(CovarianceOf(m, 0)),
      l1(CovarianceOf(m, 1));
  const int samples = 400000;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  for (int k = 0; k < samples; ++k) {
    const bool first = pick_first(rng);
    const size_t i = first ? 0 : 1;
    const Eigen::Vector3d z(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d x =
        Eigen::Vector3d(m.means[3 * i], m.means[3 * i + 1],
                        m.means[3 * i + 2]) +
        (first ? l0.matrixL() : l1.matrixL()) * z;
    sum += x;
    outer += x * x.transpose();
  }
  const Eigen::Vector3d mean = sum / samples;
  const Eigen::Matrix3d cov = outer / samples - mean * mean.transpose();
  const Eigen::Vector3d merged_mean(out.means[0], out.means[1], out.means[2]);
  EXPECT_LT((merged_mean - mean).norm(), 3e-3) << merged_mean.transpose();
  EXPECT_LT((CovarianceOf(out, 0) - cov).norm(), 3e-3 * cov.norm())
      << CovarianceOf(out, 0) << "\nvs\n"
      << cov;
  // Opacity combined as two layers; colours weighted between the two.
  const double o0 = OpacityLogitToAlpha(1.0f), o1 = OpacityLogitToAlpha(-0.5f);
  EXPECT_NEAR(OpacityLogitToAlpha(out.opacity_logits[0]),
              1 - (1 - o0) * (1 - o1), 1e-6);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(out.sh_dc[k], p0 * m.sh_dc[k] + (1 - p0) * m.sh_dc[3 + k],
                1e-5);
  }
}

TEST(Decimate, CountsSourcesAndTheSceneCentre) {
  const GaussianModel m = Scene(1001, 6);
  for (double fraction : {0.0, 0.1, 0.5, 0.75}) {
    GaussianModel out;
    std::vector<uint32_t> source;
    std::mt19937_64 rng(0);
    ApplyModelAttack(ParseModelAttack("decimate:" + std::to_string(fraction)),
                     m, rng, &out, &source);
    const size_t expected = 1001 - size_t(std::floor(fraction * 1001));
    ASSERT_EQ(out.size(), expected) << fraction;
    ASSERT_EQ(source.size(), expected);
    EXPECT_EQ(std::set<uint32_t>(source.begin(), source.end()).size(),
              expected);  // each output from a distinct input
    ExpectFinite(out);
    // The mass-weighted centre of the scene moves little: each merge keeps
    // its pair's, only the masses change (opacities combine).
    const auto centre = [](const GaussianModel& g) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      double total = 0;
      for (size_t i = 0; i < g.size(); ++i) {
        const double w = Mass(g, i);
        c += w * Eigen::Vector3d(g.means[3 * i], g.means[3 * i + 1],
                                 g.means[3 * i + 2]);
        total += w;
      }
      return Eigen::Vector3d(c / total);
    };
    EXPECT_LT((centre(out) - centre(m)).norm(), 0.05) << fraction;
  }
  // Unmerged Gaussians are unchanged: at 0 nothing changes at all.
  GaussianModel same;
  std::vector<uint32_t> source;
  Decimate(0.0, m, &same, &source);
  EXPECT_EQ(same.means, m.means);
  EXPECT_EQ(same.sh_rest, m.sh_rest);
}

TEST(Decimate, HardCasesStayFinite) {
  // Zero opacity and zero scale as readers give them (alpha 0 -> logit
  // -20, scale 0 -> log -20), infinities in a merge below.
  GaussianModel m = Scene(64, 8);
  for (size_t i = 0; i < 16; ++i) m.opacity_logits[i] = -20.f;
  for (size_t i = 16; i < 24; ++i) m.log_scales[3 * i] = kLogScaleFloor;
  for (size_t i = 24; i < 28; ++i) m.log_scales[3 * i + 1] = 60.f;  // huge
  for (size_t i = 28; i < 32; ++i)
    m.quats[4 * i] = m.quats[4 * i + 1] = m.quats[4 * i + 2] =
        m.quats[4 * i + 3] = 0.f;     // no rotation
  for (size_t i = 32; i < 40; ++i) {  // duplicates at one point
    for (int k = 0; k < 3; ++k) m.means[3 * i + k] = 0.25f;
  }
  GaussianModel out;
  std::vector<uint32_t> source;
  Decimate(0.9, m, &out, &source);
  EXPECT_EQ(out.size(), 64u - 57u);
  ExpectFinite(out);
  // Both of a pair fully transparent and flat, given as infinities.
  GaussianModel pair = Scene(2, 10), merged;
  pair.opacity_logits = {-INFINITY, -INFINITY};
  pair.log_scales[0] = pair.log_scales[4] = -INFINITY;
  merged.sh_degree = pair.sh_degree;
  merged.Resize(1);
  MergeGaussianPair(pair, 0, 1, &merged, 0);
  ExpectFinite(merged);
  EXPECT_NEAR(merged.means[0], 0.5f * (pair.means[0] + pair.means[3]), 1e-6);
  GaussianModel one = Scene(1, 9), kept;
  Decimate(0.5, one, &kept, &source);
  EXPECT_EQ(kept.size(), 1u);
}

TEST(Decimate, RefusesBadFractions) {
  for (const char* bad : {"decimate", "decimate:", "decimate:1", "decimate:1.5",
                          "decimate:-0.2", "decimate:inf"}) {
    EXPECT_THROW(ParseModelAttack(bad), Error) << bad;
  }
  EXPECT_EQ(ToString(ParseModelAttack("decimate:0.3")), "decimate:0.3");
  GaussianModel out;
  std::vector<uint32_t> source;
  EXPECT_THROW(Decimate(1.0, Scene(4, 1), &out, &source), Error);
}

}  // namespace
}  // namespace watergs
