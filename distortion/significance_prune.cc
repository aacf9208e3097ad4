// Significance pruning (see significance_prune.h).
#include "distortion/significance_prune.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "gaussian/util/error.h"

namespace watergs {

std::vector<double> SignificanceScores(const GaussianModel& model,
                                       const std::vector<RenderCamera>& cameras,
                                       Rasterizer& rasterizer,
                                       double volume_power) {
  if (cameras.empty()) {
    Fail("prune_significance: no cameras to measure significance with");
  }
  const size_t n = model.size();
  std::vector<double> weight(n, 0.0);
  for (const RenderCamera& camera : cameras) {
    rasterizer.AccumulateBlendWeights(model, camera, RenderOptions(), &weight);
  }
  if (n == 0 || volume_power == 0) return weight;
  // Log-volumes, clamped so that a degenerate scale (-Inf or +-huge log)
  // gives a tiny or large factor, never Inf * 0.
  std::vector<double> log_volume(n);
  for (size_t i = 0; i < n; ++i) {
    double sum = 0;
    for (int k = 0; k < 3; ++k) {
      const double s = model.log_scales[3 * i + k];
      sum += std::isnan(s) ? 0.0 : std::clamp(s, -100.0, 100.0);
    }
    log_volume[i] = sum;
  }
  std::vector<double> sorted = log_volume;
  const size_t p90 = std::min(n - 1, size_t(0.9 * double(n)));
  std::nth_element(sorted.begin(), sorted.begin() + p90, sorted.end());
  const double reference = sorted[p90];
  for (size_t i = 0; i < n; ++i) {
    const double factor =
        std::exp(std::min(volume_power * (log_volume[i] - reference), 600.0));
    weight[i] = std::isfinite(weight[i]) ? weight[i] * factor : 0.0;
  }
  return weight;
}

void PruneLowestScores(double fraction, const std::vector<double>& scores,
                       const GaussianModel& in, GaussianModel* out,
                       std::vector<uint32_t>* source) {
  if (!(fraction >= 0 && fraction < 1)) {
    Fail("prune_significance: the fraction must be in [0, 1), not " +
         std::to_string(fraction));
  }
  if (scores.size() != in.size()) {
    Fail("prune_significance: one score per Gaussian needed");
  }
  const size_t n = in.size();
  const size_t removed = size_t(std::floor(fraction * double(n)));
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  // Lowest scores first, ties by index: the result does not depend on the
  // sort's implementation.
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return scores[a] < scores[b];
  });
  std::vector<bool> keep(n, true);
  for (size_t k = 0; k < removed; ++k) keep[order[k]] = false;
  source->clear();
  for (size_t i = 0; i < n; ++i) {
    if (keep[i]) source->push_back(uint32_t(i));
  }
  *out = in;
  out->Filter(keep);
}

}  // namespace watergs
