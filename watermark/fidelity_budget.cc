#include "watermark/fidelity_budget.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace watergs {

double NextBlindWeight(const FidelityBudget& budget, double weight,
                       double psnr_db) {
  if (!budget.enabled() || std::isnan(psnr_db)) return weight;
  // +inf (no change at all yet) reads as far above the target.
  const double steps = std::clamp(
      (psnr_db - budget.target_db) / budget.db_per_doubling, -1.0, 1.0);
  return std::clamp(weight * std::exp2(steps), budget.min_weight,
                    budget.max_weight);
}

void CheckFidelityBudget(const FidelityBudget& budget) {
  if (!(budget.target_db >= 0) || budget.target_db > kMaxPsnrDb) {
    throw std::invalid_argument(
        "target_psnr must be in decibels, 0 (off) to 100");
  }
  if (!(budget.db_per_doubling > 0) || !std::isfinite(budget.db_per_doubling)) {
    throw std::invalid_argument("the budget's dB per doubling must be > 0");
  }
  if (!(budget.min_weight > 0) || !(budget.max_weight >= budget.min_weight) ||
      !std::isfinite(budget.max_weight)) {
    throw std::invalid_argument(
        "the budget's weight bounds must be 0 < min <= max");
  }
}

}  // namespace watergs
