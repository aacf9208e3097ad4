// The single-view spread every command prints (mean, median, p90 of the
// views' bit error rates: extract, eval, report, detect, the aggregate
// tables) against definitions computed here by brute force.
#include "watermark/view_aggregation.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace watergs {
namespace {

// Nearest-rank percentile by its definition: the smallest value that at
// least `fraction` of the values do not exceed.
double PercentileByDefinition(const std::vector<double>& values,
                              double fraction) {
  double best = INFINITY;
  for (double v : values) {
    size_t at_most = 0;
    for (double w : values) at_most += w <= v;
    if (at_most >= fraction * values.size() - 1e-9 && v < best) best = v;
  }
  return best;
}

// The median by counting: a value with as many above as below (mean of the
// two middle ones for an even count).
double MedianByCounting(const std::vector<double>& values) {
  std::vector<double> middle;
  for (double v : values) {
    size_t below = 0, above = 0;
    for (double w : values) below += w<v, above += w> v;
    const size_t n = values.size();
    if (2 * below < n + 1 && 2 * above < n + 1) middle.push_back(v);
  }
  double lo = INFINITY, hi = -INFINITY;
  for (double v : middle) lo = std::min(lo, v), hi = std::max(hi, v);
  if (values.size() % 2) return lo;
  // Two middle ranks: below the upper half and above the lower half.
  std::vector<double> sorted = values;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2,
                   sorted.end());
  const double upper = sorted[sorted.size() / 2];
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2 - 1,
                   sorted.end());
  return 0.5 * (upper + sorted[sorted.size() / 2 - 1]);
}

TEST(ViewAggregation, SpreadMatchesItsDefinitionsOnRandomViewSets) {
  std::mt19937 rng(4);
  for (int n = 1; n <= 60; ++n) {
    std::vector<double> ber;
    std::uniform_int_distribution<int> errors(0, 48);
    for (int k = 0; k < n; ++k) ber.push_back(errors(rng) / 48.0);
    const ViewBerSpread s = SpreadOfViewBer(ber);
    double mean = 0;
    for (double b : ber) mean += b;
    mean /= n;
    EXPECT_NEAR(s.mean, mean, 1e-12) << n;
    EXPECT_EQ(s.p90, PercentileByDefinition(ber, 0.9)) << n;
    EXPECT_DOUBLE_EQ(s.median, MedianByCounting(ber)) << n;
    EXPECT_EQ(s.min, PercentileByDefinition(ber, 0)) << n;
    EXPECT_EQ(s.max, PercentileByDefinition(ber, 1)) << n;
  }
}

TEST(ViewAggregation, SpreadOfTheREADMEsSixHeldOutViews) {
  // 8, 3, 1, 0, 1, 1 of 48 (docs/history.md's blind default): mean 14/288,
  // p90 the largest of 6 (ceil(5.4) = 6th), median 1.
  const ViewBerSpread s =
      SpreadOfViewBer({8 / 48.0, 3 / 48.0, 1 / 48.0, 0, 1 / 48.0, 1 / 48.0});
  EXPECT_NEAR(s.mean, 14 / 288.0, 1e-12);
  EXPECT_EQ(s.p90, 8 / 48.0);
  EXPECT_EQ(s.median, 1 / 48.0);
  const ViewBerSpread none = SpreadOfViewBer(std::vector<double>{});
  EXPECT_EQ(none.mean, 0);
  EXPECT_EQ(none.p90, 0);
}

}  // namespace
}  // namespace watergs
