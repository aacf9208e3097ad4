// How often something unmarked passes the verdict. The verdict's p-value
// assumes that each decoded bit of an unmarked image matches the claim
// independently with probability 1/2; a fixed decoder reads a fixed message
// of its own from every view of one scene, so for a fixed claim that is not
// true. This module measures it: decoded logits of unmarked views (renders of
// unmarked scenes, photo crops) are tested against fixed claims and against
// keyed claims (message XOR the stream of many keys), single views and
// aggregates of views as `extract` forms them, and the empirical rate of
// passes is set beside the binomial one at each nominal rate.
// docs/verification.md holds the measurement.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "watermark/message.h"

namespace watergs {

// Unmarked views of one scene (or one photo set): each view's L logits.
// Aggregates are only formed within a group, as `extract` aggregates views
// of one model.
struct NullGroup {
  std::string name;
  std::vector<std::vector<float>> logits;
};

// A claim tested against every unit: a fixed message, or the keyed family
// (one message under many keys).
struct NullClaim {
  std::string label;
  // One claim (fixed), or one per key (keyed).
  std::vector<Bits> bits;
};

struct NullCalibrationOptions {
  // Views averaged per unit: 1 = single views; n > 1: random sets of n
  // distinct views of one group (groups with fewer views are skipped).
  std::vector<int> aggregate_sizes = {1, 6};
  // Random sets drawn per group for each n > 1.
  int aggregates_per_group = 2000;
  // Nominal false-positive rates (the verdict's --false_positive_rate).
  std::vector<double> nominal_rates = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6};
  uint64_t seed = 0;
};

// One claim at one aggregate size at one nominal rate.
struct NullRateRow {
  std::string claim;
  int aggregate_size = 1;
  double nominal = 0;
  // The verdict's threshold: at most this many wrong bits is "present".
  int max_errors = -1;
  // P[Binomial(L, 1/2) >= L - max_errors]: the rate the verdict promises at
  // this threshold (<= nominal; the count is discrete).
  double binomial_rate = 0;
  // (unit, claim) pairs tested and how many passed.
  int64_t trials = 0, passes = 0;
  double empirical_rate = 0;
  // Claims in the row (keys), and how many of them passed on their own more
  // than twice the binomial rate: pooled over keys the rate can be right
  // while single keys are not. -1 where a claim expects fewer than 5 passes
  // (its own rate is then mostly counting noise).
  int num_claims = 1;
  int claims_above_twice = 0;
};

// Histogram of bit errors (0..L) of one claim at one aggregate size, pooled
// over groups and per group.
struct NullErrorHistogram {
  std::string claim;
  int aggregate_size = 1;
  std::vector<int64_t> pooled;
  std::vector<std::vector<int64_t>> per_group;
};

struct NullCalibration {
  int num_bits = 0;
  std::vector<std::string> group_names;
  std::vector<int> group_views;
  std::vector<NullRateRow> rows;
  std::vector<NullErrorHistogram> histograms;
  // Fraction of 1-bits per bit over every single view (decoder's lean).
  std::vector<double> bit_ones;
};

// The keyed family: `message` XOR KeyStream("null-calibration-<k>") for k <
// num_keys (keys an owner might have drawn).
NullClaim KeyedClaims(const std::string& label, const Bits& message,
                      int num_keys);

// Tests every unit of every group against every claim. Error if a group's
// logits or a claim have another length than the first view's, no group has
// a view, or an option is out of range.
NullCalibration CalibrateNull(const std::vector<NullGroup>& groups,
                              const std::vector<NullClaim>& claims,
                              const NullCalibrationOptions& options);

// P[errors <= e] for e = 0..L from a histogram.
std::vector<double> CumulativeRate(const std::vector<int64_t>& histogram);

// Markdown tables: the calibration table (nominal, threshold, binomial,
// empirical, ratio) and the tail (empirical vs binomial per error count).
std::string NullCalibrationToMarkdown(const NullCalibration& calibration);
// The same figures as JSON (histograms per group included).
std::string NullCalibrationToJson(const NullCalibration& calibration);

}  // namespace watergs
