// The hard-viewpoint pool (viewpoint_pool.h): how far a view falls short of
// the margin, sampling in proportion to it, its checkpointed state, and the
// viewpoints it draws.
#include "watermark/viewpoint_pool.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tests/common/embed_scene.h"
#include "watermark/extractor.h"

namespace watergs {
namespace {

TEST(MarginDeficit, SumsEachBitsShortfallSignedTowardsTheMessage) {
  const Bits message = {1, 0, 1};
  // Signed towards the message: 2.5, 3 (bit 0 wants a negative logit), -0.5.
  const std::vector<float> logits = {2.5f, -3.f, -0.5f};
  EXPECT_DOUBLE_EQ(MarginDeficit(logits, message, 1.0), 1.5);
  EXPECT_DOUBLE_EQ(MarginDeficit(logits, message, 3.0), 0.5 + 0 + 3.5);
  const std::vector<float> reads = {1.f, -1.f, 2.f};
  EXPECT_DOUBLE_EQ(MarginDeficit(reads, message, 1.0), 0.0);
}

TEST(ViewpointPool, SamplesEachViewInProportionToItsDeficit) {
  ViewpointPool pool(std::vector<RenderCamera>(4));
  pool.SetDeficit(0, 0.0);
  pool.SetDeficit(1, 1.0);
  pool.SetDeficit(2, 3.0);
  pool.SetDeficit(3, 0.0);
  EXPECT_EQ(pool.NumShort(), 2u);
  std::mt19937_64 rng(5);
  std::vector<int> counts(4, 0);
  const int draws = 20000;
  for (int i = 0; i < draws; ++i) ++counts.at(pool.Sample(&rng));
  EXPECT_EQ(counts[0], 0);
  EXPECT_EQ(counts[3], 0);
  // Expected 5,000 and 15,000; the binomial's sd is 61.
  EXPECT_NEAR(counts[1], 5000, 300);
  EXPECT_NEAR(counts[2], 15000, 300);
}

TEST(ViewpointPool, StartsUniformAndStopsWhenEveryViewReads) {
  ViewpointPool pool(std::vector<RenderCamera>(3));
  EXPECT_EQ(pool.NumShort(), 3u);
  std::mt19937_64 rng(1);
  std::vector<int> counts(3, 0);
  for (int i = 0; i < 3000; ++i) ++counts.at(pool.Sample(&rng));
  for (int c : counts) EXPECT_NEAR(c, 1000, 150);
  for (size_t k = 0; k < 3; ++k) pool.SetDeficit(k, 0.0);
  EXPECT_EQ(pool.Sample(&rng), -1);
}

TEST(ViewpointPool, NonFiniteDeficitsCountAsReadAndBadCheckpointsAreRefused) {
  ViewpointPool pool(std::vector<RenderCamera>(2));
  pool.SetDeficit(0, std::nan(""));
  pool.SetDeficit(1, std::numeric_limits<double>::infinity());
  EXPECT_EQ(pool.NumShort(), 0u);
  EXPECT_FALSE(pool.RestoreDeficits({1.0}));
  EXPECT_FALSE(pool.RestoreDeficits({1.0, -1.0}));
  EXPECT_FALSE(pool.RestoreDeficits({1.0, std::nan("")}));
  EXPECT_TRUE(pool.RestoreDeficits({0.0, 2.0}));
  std::mt19937_64 rng(2);
  EXPECT_EQ(pool.Sample(&rng), 1);
}

TEST(SampleViewpointsBetween, LiesBetweenTwoTrainingCamerasAndRepeatsForASeed) {
  testing::Scene s = testing::MakeScene(6, 16, 12);
  // Only the even views may be end points.
  const std::vector<size_t> train = {0, 2, 4};
  const auto a = SampleViewpointsBetween(s.views, train, 20, 11);
  const auto b = SampleViewpointsBetween(s.views, train, 20, 11);
  const auto c = SampleViewpointsBetween(s.views, train, 20, 12);
  ASSERT_EQ(a.size(), 20u);
  int differs = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].Center(), b[k].Center());
    differs += (a[k].Center() - c[k].Center()).norm() > 1e-9;
    // On a segment between two of the training centres.
    double best = std::numeric_limits<double>::infinity();
    for (size_t i : train) {
      for (size_t j : train) {
        const Eigen::Vector3d p = s.views.Camera(i).Center();
        const Eigen::Vector3d q = s.views.Camera(j).Center();
        const double len2 = (q - p).squaredNorm();
        const double t =
            len2 > 0
                ? std::clamp((a[k].Center() - p).dot(q - p) / len2, 0.0, 1.0)
                : 0.0;
        best = std::min(best, (p + t * (q - p) - a[k].Center()).norm());
      }
    }
    EXPECT_LT(best, 1e-9) << k;
  }
  EXPECT_GT(differs, 15);
}

}  // namespace
}  // namespace watergs
