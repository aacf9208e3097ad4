// Tests of the codebook clustering: the 1D quantiser is exact when values
// are few, reaches the least sum of squares (brute force), covers a sparse
// tail, its error stays near a uniform quantiser's on spread values and its
// labels name the nearest entry; k-means labels every point with its exact
// nearest centroid, never worsens with more rounds, is reproducible, and
// gives every point its own centroid when k = n.
#include "gaussian/formats/kmeans.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
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
  double worst = 0, total = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    const float error = std::abs(codebook[labels[i]] - values[i]);
    for (const float c : codebook) {
      ASSERT_LE(error, std::abs(c - values[i]) + 1e-6f) << "not the nearest";
    }
    worst = std::max(worst, double(error));
    total += error;
  }
  // A uniform quantiser of step 8 / 256 errs by a quarter step on average
  // and half a step at worst; the least-squares codebook of 20000 samples
  // spaces its entries a little unevenly, so a little more.
  const double step = 8.0 / 256;
  EXPECT_LT(total / values.size(), 1.1 * step / 4);
  EXPECT_LT(worst, 0.75 * step);
}

// Sum of squared errors of `values` against their nearest codebook entries.
double QuantisationError(const std::vector<float>& values, int k) {
  std::vector<float> codebook;
  std::vector<uint32_t> labels;
  Quantize1d(values, k, &codebook, &labels);
  double total = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    const double d = values[i] - codebook[labels[i]];
    total += d * d;
  }
  return total;
}

// The least sum of squares of `values` in k clusters by brute force: every
// way to cut the sorted values into k runs (optimal 1D clusters are runs).
double BruteForceOptimum(std::vector<float> values, int k) {
  std::sort(values.begin(), values.end());
  const int n = int(values.size());
  double best = INFINITY;
  std::vector<int> cuts(k - 1);
  std::function<void(int, int)> place = [&](int index, int from) {
    if (index == k - 1) {
      double total = 0;
      int begin = 0;
      for (int c = 0; c < k; ++c) {
        const int end = c < k - 1 ? cuts[c] : n;
        double mean = 0;
        for (int i = begin; i < end; ++i)
          mean += values[i] / double(end - begin);
        for (int i = begin; i < end; ++i) {
          total += (values[i] - mean) * (values[i] - mean);
        }
        begin = end;
      }
      best = std::min(best, total);
      return;
    }
    for (int cut = from; cut <= n - (k - 1 - index); ++cut) {
      cuts[index] = cut;
      place(index + 1, cut + 1);
    }
  };
  place(0, 1);
  return best;
}

TEST(Quantize1d, ReachesTheLeastSumOfSquares) {
  std::mt19937 rng(7);
  std::lognormal_distribution<float> skewed(0.f, 1.f);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<float> values(13);
    for (float& v : values) v = skewed(rng);
    for (int k : {2, 3, 5}) {
      EXPECT_NEAR(QuantisationError(values, k), BruteForceOptimum(values, k),
                  1e-5)
          << "trial " << trial << ", k " << k;
    }
  }
}

TEST(Quantize1d, ASparseTailGetsEntriesOfItsOwn) {
  // Log-scales of a model: a dense body and a few huge Gaussians. Lloyd from
  // the quantiles put values from 0.7 to 3.7 under one entry (1.76): the
  // renders of such a SOG were 21 dB from the model's.
  std::mt19937 rng(3);
  std::normal_distribution<float> body(-3.f, 1.f);
  std::uniform_real_distribution<float> tail(0.5f, 4.f);
  std::vector<float> values(25000);
  for (float& v : values) v = body(rng);
  for (int i = 0; i < 60; ++i) values.push_back(tail(rng));
  std::vector<float> codebook;
  std::vector<uint32_t> labels;
  Quantize1d(values, 256, &codebook, &labels);
  double worst = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    worst = std::max(worst, double(std::abs(values[i] - codebook[labels[i]])));
  }
  EXPECT_LT(worst, 0.1);
}

double SumOfSquares(const std::vector<float>& points, int dim,
                    const std::vector<float>& centroids,
                    const std::vector<uint32_t>& labels) {
  double total = 0;
  for (size_t i = 0; i < labels.size(); ++i) {
    for (int j = 0; j < dim; ++j) {
      const double d = points[i * dim + j] - centroids[labels[i] * dim + j];
      total += d * d;
    }
  }
  return total;
}

TEST(KMeans, LabelsTheNearestCentroidAndNeverWorsens) {
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.f, 1.f);
  const int dim = 9;
  std::vector<float> points(dim * 3000);
  for (float& v : points) v = noise(rng);
  double previous = HUGE_VAL;
  for (const int rounds : {1, 2, 5, 10}) {
    std::vector<float> centroids;
    std::vector<uint32_t> labels;
    KMeans(points, dim, 64, rounds, 3, &centroids, &labels);
    // Exact nearest (the k-d tree against brute force).
    for (size_t i = 0; i < labels.size(); i += 7) {
      double best = HUGE_VAL;
      for (size_t c = 0; c < 64; ++c) {
        double d = 0;
        for (int j = 0; j < dim; ++j) {
          const double e = points[i * dim + j] - centroids[c * dim + j];
          d += e * e;
        }
        best = std::min(best, d);
      }
      double mine = 0;
      for (int j = 0; j < dim; ++j) {
        const double e = points[i * dim + j] - centroids[labels[i] * dim + j];
        mine += e * e;
      }
      ASSERT_LE(mine, best * (1 + 1e-5)) << "point " << i;
    }
    const double sse = SumOfSquares(points, dim, centroids, labels);
    EXPECT_LE(sse, previous * (1 + 1e-6)) << rounds << " rounds";
    previous = sse;
    std::vector<float> again;
    std::vector<uint32_t> again_labels;
    KMeans(points, dim, 64, rounds, 3, &again, &again_labels);
    EXPECT_EQ(again, centroids) << "not reproducible";
  }
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
