#include "watermark/null_calibration.h"

#include <algorithm>
#include <bit>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

// Bits packed 64 to a word, so a comparison is a few XOR + popcounts.
using PackedBits = std::vector<uint64_t>;

PackedBits Pack(const Bits& bits) {
  PackedBits packed((bits.size() + 63) / 64, 0);
  for (size_t i = 0; i < bits.size(); ++i) {
    if (bits[i]) packed[i / 64] |= uint64_t{1} << (i % 64);
  }
  return packed;
}

int Errors(const PackedBits& a, const PackedBits& b) {
  int errors = 0;
  for (size_t w = 0; w < a.size(); ++w) errors += std::popcount(a[w] ^ b[w]);
  return errors;
}

// The bits a mean of `views` reads (mean logit > 0 -> 1, as AggregateViews).
Bits ReadBits(const std::vector<const std::vector<float>*>& views, int L) {
  Bits bits(L);
  for (int i = 0; i < L; ++i) {
    double sum = 0;
    for (const std::vector<float>* v : views) sum += (*v)[i];
    bits[i] = sum > 0;
  }
  return bits;
}

// The units (read bits) of one group at one aggregate size.
std::vector<PackedBits> GroupUnits(const NullGroup& group, int size, int count,
                                   int L, uint64_t seed) {
  std::vector<PackedBits> units;
  const int n = static_cast<int>(group.logits.size());
  if (size == 1) {
    for (const auto& v : group.logits) units.push_back(Pack(ReadBits({&v}, L)));
    return units;
  }
  if (n < size) return units;
  std::mt19937_64 rng(seed);
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (int u = 0; u < count; ++u) {
    // Partial Fisher-Yates: `size` distinct views.
    std::vector<const std::vector<float>*> views;
    for (int k = 0; k < size; ++k) {
      std::uniform_int_distribution<int> pick(k, n - 1);
      std::swap(order[k], order[pick(rng)]);
      views.push_back(&group.logits[order[k]]);
    }
    units.push_back(Pack(ReadBits(views, L)));
  }
  return units;
}

// Every unit of every group against every bits of `claim`: the histogram
// of bit errors and one row per nominal rate.
NullErrorHistogram CountClaim(const NullClaim& claim, int size,
                              const std::vector<std::vector<PackedBits>>& units,
                              const std::vector<double>& nominal_rates, int L,
                              std::vector<NullRateRow>* rows) {
  std::vector<PackedBits> packed;
  for (const Bits& b : claim.bits) packed.push_back(Pack(b));
  std::vector<int> max_errors;
  for (double nominal : nominal_rates) {
    max_errors.push_back(MaxErrorsForPresence(L, nominal));
  }
  const size_t R = nominal_rates.size();
  // Passes of each claim on its own at each rate (for the spread over keys).
  std::vector<int64_t> claim_passes(packed.size() * R, 0);
  NullErrorHistogram h{claim.label, size, std::vector<int64_t>(L + 1, 0), {}};
  for (const std::vector<PackedBits>& group_units : units) {
    std::vector<int64_t> counts(L + 1, 0);
    for (size_t k = 0; k < packed.size(); ++k) {
      for (const PackedBits& u : group_units) {
        const int e = Errors(u, packed[k]);
        ++counts[e];
        for (size_t r = 0; r < R; ++r)
          claim_passes[k * R + r] += e <= max_errors[r];
      }
    }
    for (int e = 0; e <= L; ++e) h.pooled[e] += counts[e];
    h.per_group.push_back(std::move(counts));
  }
  const int64_t trials =
      std::accumulate(h.pooled.begin(), h.pooled.end(), int64_t{0});
  for (size_t r = 0; r < R; ++r) {
    NullRateRow row;
    row.claim = claim.label;
    row.aggregate_size = size;
    row.nominal = nominal_rates[r];
    row.max_errors = max_errors[r];
    row.binomial_rate =
        row.max_errors < 0 ? 0 : BinomialTailPValue(L - row.max_errors, L);
    row.trials = trials;
    for (int e = 0; e <= row.max_errors; ++e) row.passes += h.pooled[e];
    row.empirical_rate = trials > 0 ? double(row.passes) / trials : 0;
    row.num_claims = static_cast<int>(packed.size());
    // A claim's own rate says something only where it expects a few passes.
    const double expected = row.binomial_rate * double(trials) / row.num_claims;
    row.claims_above_twice = expected >= 5 ? 0 : -1;
    for (size_t k = 0; expected >= 5 && k < packed.size(); ++k) {
      row.claims_above_twice += claim_passes[k * R + r] > 2 * expected;
    }
    rows->push_back(row);
  }
  return h;
}

void CheckInputs(const std::vector<NullGroup>& groups,
                 const std::vector<NullClaim>& claims,
                 const NullCalibrationOptions& options, int L) {
  for (const NullGroup& g : groups) {
    for (size_t v = 0; v < g.logits.size(); ++v) {
      if (static_cast<int>(g.logits[v].size()) != L) {
        Fail(g.name + ": view " + std::to_string(v) + " has " +
             std::to_string(g.logits[v].size()) + " logits, expected " +
             std::to_string(L));
      }
    }
  }
  for (const NullClaim& c : claims) {
    if (c.bits.empty()) Fail("claim " + c.label + " holds no message");
    for (const Bits& b : c.bits) {
      if (static_cast<int>(b.size()) != L) {
        Fail("claim " + c.label + " has " + std::to_string(b.size()) +
             " bits, the logits " + std::to_string(L));
      }
    }
  }
  if (options.aggregate_sizes.empty()) Fail("no aggregate size");
  for (int s : options.aggregate_sizes) {
    if (s < 1) Fail("aggregate sizes must be >= 1");
  }
  if (options.aggregates_per_group < 1) Fail("aggregates per group < 1");
  for (double r : options.nominal_rates) {
    if (!(r > 0 && r < 1)) Fail("nominal rates must be in (0, 1)");
  }
}

}  // namespace

NullClaim KeyedClaims(const std::string& label, const Bits& message,
                      int num_keys) {
  if (num_keys < 1) Fail("the keyed claims need at least one key");
  NullClaim claim{label, {}};
  for (int k = 0; k < num_keys; ++k) {
    claim.bits.push_back(
        ApplyKey(message, "null-calibration-" + std::to_string(k)));
  }
  return claim;
}

NullCalibration CalibrateNull(const std::vector<NullGroup>& groups,
                              const std::vector<NullClaim>& claims,
                              const NullCalibrationOptions& options) {
  int L = 0;
  for (const NullGroup& g : groups) {
    if (!g.logits.empty()) {
      L = static_cast<int>(g.logits[0].size());
      break;
    }
  }
  if (L == 0) Fail("no unmarked view to calibrate on");
  CheckInputs(groups, claims, options, L);

  NullCalibration result;
  result.num_bits = L;
  result.bit_ones.assign(L, 0);
  int64_t single_views = 0;
  for (const NullGroup& g : groups) {
    result.group_names.push_back(g.name);
    result.group_views.push_back(static_cast<int>(g.logits.size()));
    for (const auto& v : g.logits) {
      for (int i = 0; i < L; ++i) result.bit_ones[i] += v[i] > 0;
      ++single_views;
    }
  }
  for (double& f : result.bit_ones) f /= double(single_views);

  for (int size : options.aggregate_sizes) {
    std::vector<std::vector<PackedBits>> units;
    for (size_t g = 0; g < groups.size(); ++g) {
      units.push_back(GroupUnits(groups[g], size, options.aggregates_per_group,
                                 L, options.seed * 1000003 + g * 7919 + size));
    }
    for (const NullClaim& claim : claims) {
      std::vector<NullRateRow> rows;
      NullErrorHistogram h =
          CountClaim(claim, size, units, options.nominal_rates, L, &rows);
      result.rows.insert(result.rows.end(), rows.begin(), rows.end());
      result.histograms.push_back(std::move(h));
    }
  }
  return result;
}

std::vector<double> CumulativeRate(const std::vector<int64_t>& histogram) {
  const int64_t total =
      std::accumulate(histogram.begin(), histogram.end(), int64_t{0});
  std::vector<double> cdf(histogram.size(), 0);
  int64_t running = 0;
  for (size_t e = 0; e < histogram.size(); ++e) {
    running += histogram[e];
    cdf[e] = total > 0 ? double(running) / total : 0;
  }
  return cdf;
}

namespace {

std::string Sci(double v) {
  if (v == 0) return "0";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2g", v);
  return buf;
}

// Binomial P[errors <= e] = P[matches >= L - e].
double BinomialCdf(int e, int L) { return BinomialTailPValue(L - e, L); }

}  // namespace

std::string NullCalibrationToMarkdown(const NullCalibration& c) {
  std::ostringstream md;
  md << "Unmarked views: ";
  for (size_t g = 0; g < c.group_names.size(); ++g) {
    md << (g ? ", " : "") << c.group_names[g] << " " << c.group_views[g];
  }
  md << ". Per-bit fraction of 1s over single views: "
     << Sci(*std::min_element(c.bit_ones.begin(), c.bit_ones.end())) << " .. "
     << Sci(*std::max_element(c.bit_ones.begin(), c.bit_ones.end())) << ".\n\n"
     << "| Claim | Views averaged | Nominal rate | Present at <= wrong bits | "
        "Binomial rate | Trials | Passed | Empirical rate | Empirical / "
        "binomial | Claims above 2x |\n|---|---|---|---|---|---|---|---|---|---"
        "|\n";
  for (const NullRateRow& r : c.rows) {
    const std::string ratio =
        r.binomial_rate > 0 ? Sci(r.empirical_rate / r.binomial_rate) : "-";
    md << "| " << r.claim << " | " << r.aggregate_size << " | "
       << Sci(r.nominal) << " | " << r.max_errors << " | "
       << Sci(r.binomial_rate) << " | " << r.trials << " | " << r.passes
       << " | " << Sci(r.empirical_rate) << " | " << ratio << " | "
       << (r.claims_above_twice < 0 ? std::string("-")
                                    : std::to_string(r.claims_above_twice) +
                                          " of " + std::to_string(r.num_claims))
       << " |\n";
  }
  md << "\nTail: P[at most e of " << c.num_bits
     << " bits wrong], empirical (per claim and views averaged) vs "
        "binomial.\n\n| e | Binomial |";
  for (const NullErrorHistogram& h : c.histograms) {
    md << " " << h.claim << ", " << h.aggregate_size << " |";
  }
  md << "\n|---|---|";
  for (size_t k = 0; k < c.histograms.size(); ++k) md << "---|";
  md << "\n";
  std::vector<std::vector<double>> cdfs;
  for (const NullErrorHistogram& h : c.histograms) {
    cdfs.push_back(CumulativeRate(h.pooled));
  }
  for (int e = 0; e <= c.num_bits / 2; ++e) {
    md << "| " << e << " | " << Sci(BinomialCdf(e, c.num_bits)) << " |";
    for (const auto& cdf : cdfs) md << " " << Sci(cdf[e]) << " |";
    md << "\n";
  }
  return md.str();
}

std::string NullCalibrationToJson(const NullCalibration& c) {
  nlohmann::json j;
  j["num_bits"] = c.num_bits;
  j["groups"] = nlohmann::json::array();
  for (size_t g = 0; g < c.group_names.size(); ++g) {
    j["groups"].push_back(
        {{"name", c.group_names[g]}, {"views", c.group_views[g]}});
  }
  j["bit_ones"] = c.bit_ones;
  j["rows"] = nlohmann::json::array();
  for (const NullRateRow& r : c.rows) {
    j["rows"].push_back({{"claim", r.claim},
                         {"aggregate_size", r.aggregate_size},
                         {"nominal", r.nominal},
                         {"max_errors", r.max_errors},
                         {"binomial_rate", r.binomial_rate},
                         {"trials", r.trials},
                         {"passes", r.passes},
                         {"empirical_rate", r.empirical_rate},
                         {"num_claims", r.num_claims},
                         {"claims_above_twice", r.claims_above_twice}});
  }
  j["histograms"] = nlohmann::json::array();
  for (const NullErrorHistogram& h : c.histograms) {
    j["histograms"].push_back({{"claim", h.claim},
                               {"aggregate_size", h.aggregate_size},
                               {"pooled", h.pooled},
                               {"per_group", h.per_group}});
  }
  return j.dump(1) + "\n";
}

}  // namespace watergs
