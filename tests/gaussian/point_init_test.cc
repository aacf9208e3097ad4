// Tests of the SfM-point initialisation: k-NN distances against brute force,
// degenerate clouds, and the Inria initial parameter values.
#include "gaussian/point_init.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Mean squared distance to the k nearest other points, O(N^2), in double.
std::vector<double> BruteForceMeanSquaredKnn(const std::vector<float>& xyz,
                                             int k) {
  const size_t n = xyz.size() / 3;
  std::vector<double> result(n);
  for (size_t i = 0; i < n; ++i) {
    std::vector<double> d2;
    for (size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double s = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = double(xyz[3 * i + c]) - double(xyz[3 * j + c]);
        s += d * d;
      }
      d2.push_back(s);
    }
    const size_t m = std::min<size_t>(k, d2.size());
    std::partial_sort(d2.begin(), d2.begin() + m, d2.end());
    double sum = 0;
    for (size_t j = 0; j < m; ++j) sum += d2[j];
    result[i] = sum / m;
  }
  return result;
}

std::vector<float> RandomPoints(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(-5.f, 5.f);
  std::vector<float> xyz(3 * n);
  for (float& v : xyz) v = uniform(rng);
  return xyz;
}

TEST(PointInit, KnnDistancesMatchBruteForce) {
  std::vector<float> xyz = RandomPoints(3000, 1);
  // A tight cluster and an exact duplicate pair exercise near-ties.
  for (int i = 0; i < 20; ++i) {
    xyz.insert(xyz.end(), {1.f + 1e-3f * i, 2.f, 3.f});
  }
  xyz.insert(xyz.end(), {4.f, 4.f, 4.f, 4.f, 4.f, 4.f});
  const std::vector<float> fast = MeanSquaredNeighbourDistances(xyz, 3);
  const std::vector<double> slow = BruteForceMeanSquaredKnn(xyz, 3);
  ASSERT_EQ(fast.size(), slow.size());
  for (size_t i = 0; i < slow.size(); ++i) {
    // Float distances: a few ulps of the squared coordinates (~25).
    EXPECT_NEAR(fast[i], slow[i], 1e-5 * slow[i] + 1e-5) << "point " << i;
  }
}

TEST(PointInit, ManyDuplicatesGiveZeroDistance) {
  std::vector<float> xyz;
  for (int i = 0; i < 10; ++i) xyz.insert(xyz.end(), {0.5f, -1.f, 2.f});
  xyz.insert(xyz.end(), {3.f, 3.f, 3.f});
  const std::vector<float> d2 = MeanSquaredNeighbourDistances(xyz, 3);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(d2[i], 0.f) << i;
  const double far = 2.5 * 2.5 + 4 * 4 + 1;
  EXPECT_NEAR(d2[10], far, 1e-5 * far);
  // log(sqrt(1e-7)) after the clamp, never -inf.
  const GaussianModel model =
      InitGaussiansFromPoints(xyz, std::vector<float>(xyz.size(), .5f), 0);
  EXPECT_NEAR(model.log_scales[0], 0.5 * std::log(1e-7), 1e-5);
  EXPECT_EQ(model.CountNonFinite(), 0u);
}

TEST(PointInit, FewerThanFourPoints) {
  EXPECT_TRUE(MeanSquaredNeighbourDistances({}, 3).empty());
  EXPECT_EQ(MeanSquaredNeighbourDistances({1.f, 2.f, 3.f}, 3),
            std::vector<float>{1.f});
  const std::vector<float> two = {0.f, 0.f, 0.f, 3.f, 0.f, 4.f};
  EXPECT_EQ(MeanSquaredNeighbourDistances(two, 3),
            (std::vector<float>{25.f, 25.f}));
  const std::vector<float> three = {0.f, 0.f, 0.f, 1.f, 0.f,
                                    0.f, 0.f, 2.f, 0.f};
  const std::vector<double> expected = BruteForceMeanSquaredKnn(three, 3);
  const std::vector<float> got = MeanSquaredNeighbourDistances(three, 3);
  for (int i = 0; i < 3; ++i) EXPECT_FLOAT_EQ(got[i], expected[i]);
  EXPECT_FLOAT_EQ(got[0], 2.5f);  // (1 + 4) / 2
}

TEST(PointInit, InitialParametersFollowInria) {
  const std::vector<float> xyz = RandomPoints(200, 2);
  std::vector<float> rgb(xyz.size());
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (float& c : rgb) c = unit(rng);
  const GaussianModel model = InitGaussiansFromPoints(xyz, rgb, 3);
  const std::vector<double> d2 = BruteForceMeanSquaredKnn(xyz, 3);
  ASSERT_EQ(model.size(), 200u);
  EXPECT_EQ(model.means, xyz);
  EXPECT_EQ(model.sh_rest.size(), 200u * 45);
  EXPECT_TRUE(std::all_of(model.sh_rest.begin(), model.sh_rest.end(),
                          [](float v) { return v == 0.f; }));
  const double c0 = 0.5 / std::sqrt(M_PI);  // SH band-0 constant
  for (size_t i = 0; i < model.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(model.sh_dc[3 * i + c], (rgb[3 * i + c] - 0.5) / c0, 1e-5);
      EXPECT_NEAR(model.log_scales[3 * i + c], std::log(std::sqrt(d2[i])),
                  1e-5);
    }
    EXPECT_EQ(model.quats[4 * i], 1.f);
    EXPECT_EQ(model.quats[4 * i + 1], 0.f);
    EXPECT_EQ(model.quats[4 * i + 2], 0.f);
    EXPECT_EQ(model.quats[4 * i + 3], 0.f);
    EXPECT_NEAR(1.0 / (1.0 + std::exp(-model.opacity_logits[i])), 0.1, 1e-7);
  }
}

TEST(PointInit, RefusesBadInput) {
  EXPECT_THROW(InitGaussiansFromPoints({1.f, 2.f}, {1.f, 2.f}, 3), Error);
  EXPECT_THROW(InitGaussiansFromPoints({1.f, 2.f, 3.f}, {1.f, 2.f}, 3), Error);
  EXPECT_THROW(InitGaussiansFromPoints({1.f, NAN, 3.f}, {1.f, 1.f, 1.f}, 3),
               Error);
  EXPECT_THROW(InitGaussiansFromPoints({1.f, 2.f, 3.f}, {1.f, 1.f, 1.f}, 4),
               Error);
}

}  // namespace
}  // namespace watergs
