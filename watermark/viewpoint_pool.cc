// Hard-viewpoint replay for the embedding (see viewpoint_pool.h).
#include "watermark/viewpoint_pool.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace watergs {

double MarginDeficit(const std::vector<float>& logits, const Bits& message,
                     double margin) {
  double deficit = 0;
  for (size_t i = 0; i < message.size(); ++i) {
    const double signed_logit = message[i] ? logits[i] : -logits[i];
    deficit += std::max(0.0, margin - signed_logit);
  }
  return deficit;
}

ViewpointPool::ViewpointPool(std::vector<RenderCamera> cameras)
    : cameras_(std::move(cameras)), deficits_(cameras_.size(), 1.0) {}

void ViewpointPool::SetDeficit(size_t k, double deficit) {
  // A NaN logit must not turn into a weight that poisons the sampler.
  deficits_.at(k) = std::isfinite(deficit) && deficit > 0 ? deficit : 0.0;
}

bool ViewpointPool::RestoreDeficits(const std::vector<double>& deficits) {
  if (deficits.size() != deficits_.size()) return false;
  for (double d : deficits) {
    if (!(std::isfinite(d) && d >= 0)) return false;
  }
  deficits_ = deficits;
  return true;
}

size_t ViewpointPool::NumShort() const {
  return std::count_if(deficits_.begin(), deficits_.end(),
                       [](double d) { return d > 0; });
}

int ViewpointPool::Sample(std::mt19937_64* rng) const {
  const double total = std::accumulate(deficits_.begin(), deficits_.end(), 0.0);
  if (!(total > 0)) return -1;
  double u = std::uniform_real_distribution<double>(0, total)(*rng);
  for (size_t k = 0; k < deficits_.size(); ++k) {
    if (deficits_[k] <= 0) continue;
    if (u < deficits_[k]) return static_cast<int>(k);
    u -= deficits_[k];
  }
  // Rounding left u at the end: the last view with weight.
  for (size_t k = deficits_.size(); k-- > 0;) {
    if (deficits_[k] > 0) return static_cast<int>(k);
  }
  return -1;
}

}  // namespace watergs
