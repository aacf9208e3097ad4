#include "watermark/null_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/util/error.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

constexpr int kBits = 48;

// `n` views whose logits are lean + N(0, noise) per bit.
NullGroup Scene(const std::string& name, int n, const std::vector<float>& lean,
                float noise, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0, noise);
  NullGroup g{name, {}};
  for (int v = 0; v < n; ++v) {
    std::vector<float> logits(lean);
    for (float& l : logits) l += normal(rng);
    g.logits.push_back(logits);
  }
  return g;
}

const NullRateRow& Row(const NullCalibration& c, const std::string& claim,
                       int size, double nominal) {
  for (const NullRateRow& r : c.rows) {
    if (r.claim == claim && r.aggregate_size == size && r.nominal == nominal) {
      return r;
    }
  }
  throw std::runtime_error("no row " + claim);
}

// |observed - expected| within 5 binomial standard deviations.
void ExpectBinomial(int64_t passes, int64_t trials, double rate) {
  const double mean = trials * rate;
  const double sigma = std::sqrt(trials * rate * (1 - rate));
  EXPECT_NEAR(double(passes), mean, 5 * sigma + 1)
      << passes << " of " << trials << " at rate " << rate;
}

TEST(NullCalibration, FairCoinViewsPassAtTheBinomialRate) {
  // Independent, unbiased logits: exactly the verdict's null hypothesis.
  const NullGroup g = Scene("coins", 40000, std::vector<float>(kBits, 0), 1, 1);
  const Bits claim = ParseMessage("text:WGS-26", kBits);
  NullCalibrationOptions options;
  options.aggregate_sizes = {1};
  options.nominal_rates = {1e-2, 1e-3};
  const NullCalibration c = CalibrateNull({g}, {{"fixed", {claim}}}, options);
  ASSERT_EQ(c.rows.size(), 2u);
  const NullRateRow& r = Row(c, "fixed", 1, 1e-2);
  EXPECT_EQ(r.trials, 40000);
  EXPECT_EQ(r.max_errors, MaxErrorsForPresence(kBits, 1e-2));
  EXPECT_DOUBLE_EQ(r.binomial_rate,
                   BinomialTailPValue(kBits - r.max_errors, kBits));
  EXPECT_LE(r.binomial_rate, 1e-2);
  ExpectBinomial(r.passes, r.trials, r.binomial_rate);
  EXPECT_GT(r.passes, 100);  // the rate is ~0.7%: a counter that never counts
  for (double f : c.bit_ones) EXPECT_NEAR(f, 0.5, 0.02);
}

TEST(NullCalibration, AScenePassesAFixedClaimItLeansToButNotKeyedClaims) {
  // Every view of this scene leans towards the claim's bits: a fixed claim
  // passes far beyond the binomial rate, keyed claims do not.
  const Bits claim = ParseMessage("text:WGS-26", kBits);
  std::vector<float> lean(kBits);
  for (int i = 0; i < kBits; ++i) lean[i] = claim[i] ? 1.5f : -1.5f;
  const NullGroup g = Scene("leaning scene", 200, lean, 1, 2);
  NullCalibrationOptions options;
  options.aggregate_sizes = {1, 6};
  options.aggregates_per_group = 1000;
  options.nominal_rates = {1e-2, 1e-4};
  const NullClaim keyed = KeyedClaims("keyed", claim, 2000);
  const NullCalibration c =
      CalibrateNull({g}, {{"fixed", {claim}}, keyed}, options);
  // One view: P(bit right) = P(N(1.5, 1) > 0) = 0.93: most views pass 1e-4.
  EXPECT_GT(Row(c, "fixed", 1, 1e-4).empirical_rate, 0.5);
  // Six views averaged: every one passes.
  EXPECT_EQ(Row(c, "fixed", 6, 1e-4).passes, 1000);
  EXPECT_EQ(Row(c, "fixed", 6, 1e-4).trials, 1000);
  // At 1e-2 the claim expects 6.6 passes of 1000 and had 1000; at 1e-4 it
  // expects 0.03: too few for its own rate to say anything (-1).
  EXPECT_EQ(Row(c, "fixed", 6, 1e-2).claims_above_twice, 1);
  EXPECT_EQ(Row(c, "fixed", 6, 1e-4).claims_above_twice, -1);
  // Keyed: the claim is a fair coin per bit whatever the scene reads.
  const NullRateRow& k = Row(c, "keyed", 6, 1e-2);
  EXPECT_EQ(k.trials, 1000 * 2000);
  EXPECT_LT(k.empirical_rate, 3 * k.binomial_rate);
  EXPECT_GT(k.empirical_rate, k.binomial_rate / 3);
  // Pooled over keys the rate is right, yet each key that happens to match
  // this scene's read passes every time: the keys above twice the rate are
  // those whose claimed bits differ from the scene's (the claim's, here: a
  // six-view mean misreads a bit with probability Phi(-1.5 sqrt 6) = 1e-4)
  // in at most the rate's wrong bits, counted here from the keys alone
  // (about 0.0066 x 2000 = 13); a bit misread near the threshold may move
  // one key either way.
  EXPECT_EQ(k.num_claims, 2000);
  int matching_keys = 0;
  for (int n = 0; n < 2000; ++n) {
    const Bits keyed_claim =
        ApplyKey(claim, "null-calibration-" + std::to_string(n));
    matching_keys += HammingDistance(keyed_claim, claim) <= k.max_errors;
  }
  EXPECT_GE(matching_keys, 5);
  EXPECT_NEAR(k.claims_above_twice, matching_keys, 2);
}

TEST(NullCalibration, AggregatesNeedEnoughViewsAndCountPerGroup) {
  const std::vector<float> zero(kBits, 0);
  const NullGroup big = Scene("big", 10, zero, 1, 3);
  const NullGroup small = Scene("small", 3, zero, 1, 4);
  NullCalibrationOptions options;
  options.aggregate_sizes = {1, 6};
  options.aggregates_per_group = 50;
  const Bits claim(kBits, 1);
  const NullCalibration c =
      CalibrateNull({big, small}, {{"fixed", {claim}}}, options);
  ASSERT_EQ(c.histograms.size(), 2u);
  const NullErrorHistogram& single = c.histograms[0];
  const NullErrorHistogram& six = c.histograms[1];
  EXPECT_EQ(single.aggregate_size, 1);
  EXPECT_EQ(six.aggregate_size, 6);
  auto total = [](const std::vector<int64_t>& h) {
    int64_t t = 0;
    for (int64_t v : h) t += v;
    return t;
  };
  EXPECT_EQ(total(single.per_group[0]), 10);
  EXPECT_EQ(total(single.per_group[1]), 3);
  EXPECT_EQ(total(six.per_group[0]), 50);
  EXPECT_EQ(total(six.per_group[1]), 0);  // 3 views: no set of 6
  EXPECT_EQ(total(six.pooled), 50);
  // Claim all ones: a view's bit errors are its count of logits <= 0.
  int errors0 = 0;
  for (float l : big.logits[0]) errors0 += l <= 0;
  EXPECT_GE(single.per_group[0][errors0], 1);
}

TEST(NullCalibration, CumulativeRateAndTables) {
  const std::vector<double> cdf = CumulativeRate({1, 0, 3});
  ASSERT_EQ(cdf.size(), 3u);
  EXPECT_DOUBLE_EQ(cdf[0], 0.25);
  EXPECT_DOUBLE_EQ(cdf[1], 0.25);
  EXPECT_DOUBLE_EQ(cdf[2], 1.0);
  const NullGroup g = Scene("s", 20, std::vector<float>(kBits, 0), 1, 5);
  NullCalibrationOptions options;
  options.aggregate_sizes = {1};
  const NullCalibration c =
      CalibrateNull({g}, {{"fixed", {Bits(kBits, 0)}}}, options);
  const std::string md = NullCalibrationToMarkdown(c);
  EXPECT_NE(md.find("| fixed | 1 | 0.01 |"), std::string::npos) << md;
  EXPECT_NE(md.find("s 20"), std::string::npos);
  EXPECT_NE(NullCalibrationToJson(c).find("\"per_group\""), std::string::npos);
}

TEST(NullCalibration, RefusesMismatchedInputs) {
  const NullGroup g = Scene("s", 5, std::vector<float>(kBits, 0), 1, 6);
  NullCalibrationOptions options;
  EXPECT_THROW(CalibrateNull({g}, {{"short", {Bits(40, 0)}}}, options), Error);
  EXPECT_THROW(CalibrateNull({}, {{"c", {Bits(kBits, 0)}}}, options), Error);
  NullGroup ragged = g;
  ragged.logits[2].pop_back();
  EXPECT_THROW(CalibrateNull({ragged}, {{"c", {Bits(kBits, 0)}}}, options),
               Error);
  options.aggregate_sizes = {0};
  EXPECT_THROW(CalibrateNull({g}, {{"c", {Bits(kBits, 0)}}}, options), Error);
  EXPECT_THROW(KeyedClaims("k", Bits(kBits, 0), 0), Error);
}

}  // namespace
}  // namespace watergs
