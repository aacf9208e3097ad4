// Tests of the blind weight's PSNR budget (embed --target_psnr).
#include "watermark/fidelity_budget.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace watergs {
namespace {

TEST(FidelityBudget, DoublesAboveTheTargetAndHalvesBelowByTheDistance) {
  FidelityBudget b;
  b.target_db = 36;
  b.db_per_doubling = 2;
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 38), 1.0);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 34), 0.25);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 36), 0.5);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 37), 0.5 * std::sqrt(2.0));
  // One check moves the weight by a factor of 2 at most.
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 60), 1.0);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, 10), 0.25);
  // Renders equal to the input's read +inf: far above.
  EXPECT_DOUBLE_EQ(
      NextBlindWeight(b, 0.5, std::numeric_limits<double>::infinity()), 1.0);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.5, std::nan("")), 0.5);
}

TEST(FidelityBudget, StaysWithinItsBoundsAndDoesNothingWhenOff) {
  FidelityBudget b;
  b.target_db = 30;
  double w = 1;
  for (int i = 0; i < 100; ++i) w = NextBlindWeight(b, w, 50);
  EXPECT_DOUBLE_EQ(w, b.max_weight);
  for (int i = 0; i < 100; ++i) w = NextBlindWeight(b, w, 5);
  EXPECT_DOUBLE_EQ(w, b.min_weight);
  b.target_db = 0;
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.7, 50), 0.7);
  EXPECT_DOUBLE_EQ(NextBlindWeight(b, 0.7, 5), 0.7);
}

TEST(FidelityBudget, RefusesTargetsAndStepsThatAreNotDecibels) {
  FidelityBudget b;
  EXPECT_NO_THROW(CheckFidelityBudget(b));
  for (double bad : {-1.0, 101.0, std::nan("")}) {
    b.target_db = bad;
    EXPECT_THROW(CheckFidelityBudget(b), std::invalid_argument) << bad;
  }
  b.target_db = 36;
  b.db_per_doubling = 0;
  EXPECT_THROW(CheckFidelityBudget(b), std::invalid_argument);
  b.db_per_doubling = 2;
  b.min_weight = 2;
  b.max_weight = 1;
  EXPECT_THROW(CheckFidelityBudget(b), std::invalid_argument);
}

}  // namespace
}  // namespace watergs
