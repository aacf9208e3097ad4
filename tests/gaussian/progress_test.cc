// Tests of the progress-line helpers: the running average shown with a
// loss, and the duration format of the ETA.
#include "gaussian/progress.h"

#include <gtest/gtest.h>

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

TEST(FormatDuration, UsesTheLargestUnitThatFits) {
  EXPECT_EQ(FormatDuration(12.3), "12.3s");
  EXPECT_EQ(FormatDuration(185), "3m05s");
  EXPECT_EQ(FormatDuration(3720), "1h02m");
}

}  // namespace
}  // namespace watergs
