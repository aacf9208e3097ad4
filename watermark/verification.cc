#include "watermark/verification.h"

#include <cmath>

#include "gaussian/util/error.h"

namespace watergs {

double BinomialTailPValue(int matching, int num_bits) {
  if (num_bits <= 0 || matching < 0 || matching > num_bits) {
    Fail("p-value: " + std::to_string(matching) + " matching bits out of " +
         std::to_string(num_bits) + " is not a valid count");
  }
  if (matching == 0) return 1.0;  // P[X >= 0], exactly.
  // Sum C(n, k) / 2^n in log space: exact to double precision for any n a
  // decoder has, and never overflows.
  const double n = num_bits;
  const double log_half_n = -n * std::log(2.0);
  double tail = 0.0;
  for (int k = matching; k <= num_bits; ++k) {
    const double log_c =
        std::lgamma(n + 1) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1);
    tail += std::exp(log_c + log_half_n);
  }
  return std::min(1.0, tail);
}

Verdict Decide(double p_value, const VerificationThresholds& thresholds) {
  if (p_value <= thresholds.present_p) return Verdict::kPresent;
  if (p_value > thresholds.absent_p) return Verdict::kAbsent;
  return Verdict::kInconclusive;
}

std::string ToString(Verdict verdict) {
  switch (verdict) {
    case Verdict::kPresent:
      return "watermark present";
    case Verdict::kAbsent:
      return "watermark absent";
    case Verdict::kInconclusive:
      return "inconclusive";
  }
  return "inconclusive";
}

int MaxErrorsForPresence(int num_bits, double present_p) {
  int best = -1;
  for (int errors = 0; errors <= num_bits; ++errors) {
    if (BinomialTailPValue(num_bits - errors, num_bits) <= present_p) {
      best = errors;
    } else {
      break;
    }
  }
  return best;
}

}  // namespace watergs
