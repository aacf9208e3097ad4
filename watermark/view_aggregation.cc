// Aggregation of decoded views into one verdict (see view_aggregation.h).
#include "watermark/view_aggregation.h"

#include <algorithm>
#include <string>
#include <utility>

#include "gaussian/util/error.h"

namespace watergs {

ViewBerSpread SpreadOfViewBer(std::vector<double> view_ber) {
  ViewBerSpread spread;
  const size_t m = view_ber.size();
  if (m == 0) return spread;
  std::sort(view_ber.begin(), view_ber.end());
  spread.min = view_ber.front();
  spread.max = view_ber.back();
  spread.median =
      m % 2 ? view_ber[m / 2] : 0.5 * (view_ber[m / 2 - 1] + view_ber[m / 2]);
  spread.p90 = view_ber[(9 * m + 9) / 10 - 1];
  for (double b : view_ber) spread.mean += b / double(m);
  return spread;
}

ViewBerSpread SpreadOfViewBer(const ExtractionResult& result) {
  std::vector<double> view_ber;
  const double bits = double(result.recovered.size());
  for (const ViewDecode& view : result.views) {
    if (view.bit_errors >= 0) view_ber.push_back(view.bit_errors / bits);
  }
  return SpreadOfViewBer(std::move(view_ber));
}

ExtractionResult AggregateViews(std::vector<ViewDecode> views, int num_bits,
                                const Bits* expected,
                                const VerificationThresholds& thresholds) {
  if (views.empty()) Fail("no views to aggregate");
  if (expected && static_cast<int>(expected->size()) != num_bits) {
    Fail("expected message has " + std::to_string(expected->size()) +
         " bits, the decoder reads " + std::to_string(num_bits));
  }
  ExtractionResult result;
  result.thresholds = thresholds;
  result.mean_logits.assign(num_bits, 0.f);
  std::vector<double> view_ber;
  for (ViewDecode& view : views) {
    if (static_cast<int>(view.logits.size()) != num_bits) {
      Fail(view.name + ": " + std::to_string(view.logits.size()) +
           " logits, expected " + std::to_string(num_bits));
    }
    for (int i = 0; i < num_bits; ++i) {
      result.mean_logits[i] += view.logits[i] / views.size();
    }
    if (expected) {
      Bits bits(num_bits);
      for (int i = 0; i < num_bits; ++i) bits[i] = view.logits[i] > 0;
      view.bit_errors = HammingDistance(bits, *expected);
      view_ber.push_back(double(view.bit_errors) / num_bits);
    }
  }
  result.views = std::move(views);
  result.recovered.resize(num_bits);
  for (int i = 0; i < num_bits; ++i) {
    result.recovered[i] = result.mean_logits[i] > 0;
  }
  if (expected) {
    result.has_expected = true;
    result.expected = *expected;
    result.bit_errors = HammingDistance(result.recovered, *expected);
    result.ber = double(result.bit_errors) / num_bits;
    const ViewBerSpread spread = SpreadOfViewBer(std::move(view_ber));
    result.min_view_ber = spread.min;
    result.median_view_ber = spread.median;
    result.max_view_ber = spread.max;
    result.mean_view_ber = spread.mean;
    result.p90_view_ber = spread.p90;
    result.p_value = BinomialTailPValue(num_bits - result.bit_errors, num_bits);
    result.verdict = Decide(result.p_value, thresholds);
  }
  return result;
}

}  // namespace watergs
