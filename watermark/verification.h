// The owner's statistical evidence: how unlikely it is that an unmarked model
// decodes to a message this close to the claimed one.
#pragma once

#include <string>

namespace watergs {

// Null hypothesis: the model is unmarked, so each decoded bit matches the
// claimed message independently with probability 1/2.
// Returns P[X >= matching] for X ~ Binomial(num_bits, 1/2), exactly.
double BinomialTailPValue(int matching, int num_bits);

enum class Verdict { kPresent, kAbsent, kInconclusive };

struct VerificationThresholds {
  // p-value at or below which the watermark is declared present: the
  // false-positive rate on unmarked models.
  double present_p = 1e-6;
  // p-value above which the watermark is declared absent (the decoded
  // message is what chance gives).
  double absent_p = 1e-2;
};

// Verdict for a p-value.
Verdict Decide(double p_value, const VerificationThresholds& thresholds);
// "watermark present" / "watermark absent" / "inconclusive".
std::string ToString(Verdict verdict);

// Largest bit error count still declared present at `present_p` for
// `num_bits` bits (-1 if none is).
int MaxErrorsForPresence(int num_bits, double present_p);

}  // namespace watergs
