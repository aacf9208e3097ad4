// The blind term's weight steered to a PSNR budget (embed --target_psnr): a
// scene whose message costs little fidelity spends its headroom on the blind
// reading, one that costs much keeps it.
#ifndef WATERGS_WATERMARK_FIDELITY_BUDGET_H_
#define WATERGS_WATERMARK_FIDELITY_BUDGET_H_

namespace watergs {

// The highest PSNR a check counts (dB): an untouched view reads +inf.
inline constexpr double kMaxPsnrDb = 100;

struct FidelityBudget {
  // PSNR (dB) of the watermarked renders against the input model's renders
  // the run steers towards; <= 0: off (the weight stays as given).
  double target_db = 0;
  // dB above or below the target that double or halve the weight at one
  // check (a check moves it by at most a factor of 2 either way).
  double db_per_doubling = 2;
  // Bounds of the weight, whatever the renders read.
  double min_weight = 1.0 / 64;
  double max_weight = 64;
  bool enabled() const { return target_db > 0; }
};

// The blind term's weight after a check that measured `psnr_db` against the
// input model's renders (+inf when identical): weight * 2^(clamp((psnr_db -
// target) / db_per_doubling, -1, 1)), kept within the bounds. A NaN PSNR
// leaves the weight as it is. Unchanged when the budget is off.
double NextBlindWeight(const FidelityBudget& budget, double weight,
                       double psnr_db);

// Throws std::invalid_argument naming the bad field (--target_psnr in
// decibels, a positive step and 0 < min <= max).
void CheckFidelityBudget(const FidelityBudget& budget);

}  // namespace watergs

#endif  // WATERGS_WATERMARK_FIDELITY_BUDGET_H_
