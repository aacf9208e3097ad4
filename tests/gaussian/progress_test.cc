// Tests of the progress-line helpers: the running average shown with a
// loss, the ETA estimate and the duration format of the ETA.
#include "gaussian/progress.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

namespace watergs {
namespace {

TEST(RunningAverage, FirstValueStartsItThenOldValuesDecayByKeep) {
  RunningAverage average(0.75);
  EXPECT_EQ(average.Add(8.0), 8.0);
  EXPECT_DOUBLE_EQ(average.Add(0.0), 6.0);  // 0.75 * 8
  EXPECT_DOUBLE_EQ(average.Add(4.0), 5.5);  // 0.75 * 6 + 0.25 * 4
  EXPECT_DOUBLE_EQ(average.value(), 5.5);
}

TEST(RunningAverage, ZeroIsAValueNotAnUnsetMarker) {
  RunningAverage average(0.5);
  average.Add(0.0);
  EXPECT_DOUBLE_EQ(average.Add(2.0), 1.0);
}

// Steps that got slower (more Gaussians): the ETA is at the recent rate,
// not the average since the start.
TEST(EtaEstimator, UsesTheRecentRateNotTheAverageSinceTheStart) {
  EtaEstimator eta(30);
  double t = 0;
  for (int step = 1; step <= 1000; ++step) {
    t += step <= 500 ? 0.01 : 0.1;  // 5 s, then 50 s
    eta.Add(step, t);
  }
  // 1000 steps left at 0.1 s (the average since the start says 55 s).
  EXPECT_NEAR(eta.Remaining(2000), 100.0, 1.0);
  EXPECT_DOUBLE_EQ(eta.Remaining(1000), 0.0);
}

// The case: at step 959 of 2000 the Gaussian count was still
// growing; a step costs in proportion to it.
TEST(EtaEstimator, ExtrapolatesTheLoadUntilItStopsGrowing) {
  const double cost = 1e-5;  // seconds per step and Gaussian
  const auto load = [](int64_t step) { return 1000.0 + 10.0 * step; };
  EtaEstimator eta(30);
  double t = 0;
  for (int64_t step = 1; step <= 959; ++step) {
    t += cost * load(step);
    eta.Add(step, t, load(step));
  }
  // Growing to the end: the exact sum of the remaining steps' costs.
  double growing = 0, stopping = 0;
  for (int64_t step = 960; step <= 2000; ++step) {
    growing += cost * load(step);
    stopping += cost * load(std::min<int64_t>(step, 1500));
  }
  EXPECT_NEAR(eta.Remaining(2000, 15000), growing, 0.02 * growing);
  EXPECT_NEAR(eta.Remaining(2000, 1500), stopping, 0.02 * stopping);
  // The load held at its current value would say far less.
  EXPECT_GT(eta.Remaining(2000, 15000), 1.3 * cost * load(959) * 1041);
}

TEST(FormatDuration, UsesTheLargestUnitThatFits) {
  EXPECT_EQ(FormatDuration(12.3), "12.3s");
  EXPECT_EQ(FormatDuration(185), "3m05s");
  EXPECT_EQ(FormatDuration(3720), "1h02m");
}

}  // namespace
}  // namespace watergs
