// Tests of the codebook clustering: the 1D quantiser is exact when values
// are few, its error stays within half a step on spread values and its
// labels name the nearest entry; k-means recovers separated clusters, gives
// every point its own centroid when k = n, and is reproducible.
#include "gaussian/kmeans.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace watergs {
namespace {

TEST(Quantize1d, FewDistinctValuesAreExact) {
  const std::vector<float> values = {3.f, -1.f, 3.f, 0.5f, -1.f, 0.5f};
  std::vector<float> codebook;
  std::vector<uint32_t> labels;
  Quantize1d(values, 256, &codebook, &labels);
  EXPECT_EQ(codebook, (std::vector<float>{-1.f, 0.5f, 3.f}));
  for (size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(codebook[labels[i]], values[i]);
  }
}

TEST(Quantize1d, LabelsTheNearestEntryWithinHalfAStep) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-4.f, 4.f);
  std::vector<float> values(20000);
  for (float& v : values) v = u(rng);
  std::vector<float> codebook;
  std::vector<uint32_t> labels;
  Quantize1d(values, 256, &codebook, &labels);
  ASSERT_EQ(codebook.size(), 256u);
  EXPECT_TRUE(std::is_sorted(codebook.begin(), codebook.end()));
  double worst = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    const float error = std::abs(codebook[labels[i]] - values[i]);
    for (const float c : codebook) {
      ASSERT_LE(error, std::abs(c - values[i]) + 1e-6f) << "not the nearest";
    }
    worst = std::max(worst, double(error));
  }
  EXPECT_LT(worst, 8.0 / 256);  // a uniform step is 8 / 256; half is 1/64
}

TEST(KMeans, RecoversSeparatedClusters) {
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.f, 0.01f);
  const float centres[4][2] = {{0, 0}, {5, 0}, {0, 5}, {5, 5}};
  std::vector<float> points;
  for (int i = 0; i < 400; ++i) {
    points.push_back(centres[i % 4][0] + noise(rng));
    points.push_back(centres[i % 4][1] + noise(rng));
  }
  std::vector<float> centroids;
  std::vector<uint32_t> labels;
  KMeans(points, 2, 4, 10, 3, &centroids, &labels);
  for (int i = 0; i < 400; ++i) {
    EXPECT_EQ(labels[i], labels[i % 4]) << "point " << i;
    const float* c = &centroids[2 * labels[i]];
    EXPECT_NEAR(c[0], centres[i % 4][0], 0.01);
    EXPECT_NEAR(c[1], centres[i % 4][1], 0.01);
  }
  std::vector<float> again;
  std::vector<uint32_t> again_labels;
  KMeans(points, 2, 4, 10, 3, &again, &again_labels);
  EXPECT_EQ(again, centroids);
  EXPECT_EQ(again_labels, labels);
}

TEST(KMeans, OneClusterPerPointIsExact) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> points(45 * 64);
  for (float& v : points) v = u(rng);
  std::vector<float> centroids;
  std::vector<uint32_t> labels;
  KMeans(points, 45, 64, 3, 5, &centroids, &labels);
  for (size_t i = 0; i < 64; ++i) {
    for (size_t j = 0; j < 45; ++j) {
      EXPECT_EQ(centroids[45 * labels[i] + j], points[45 * i + j]);
    }
  }
}

}  // namespace
}  // namespace watergs
