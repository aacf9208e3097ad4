#include "watermark/distortion_choice.h"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// As the decoder reads: logit > 0 is bit 1.
bool Reads(float logit, bool bit) { return (logit > 0) == bit; }

}  // namespace

DistortionChoice::DistortionChoice(
    const std::vector<DistortionSpec>& candidates) {
  for (const DistortionSpec& spec : candidates) {
    if (spec.kind == DistortionKind::kIdentity) continue;
    DistortionCandidate c;
    c.spec = spec;
    candidates_.push_back(c);
  }
}

std::vector<DistortionSpec> DistortionChoice::Simulated() const {
  std::vector<DistortionSpec> specs(1);  // The identity, weight 1.
  for (const DistortionCandidate& c : candidates_) {
    if (c.simulated()) specs.push_back(c.spec);
  }
  return specs;
}

bool DistortionChoice::Ready(const std::vector<std::vector<float>>& plain,
                             size_t num_views, const Bits& message,
                             double margin) {
  if (num_views == 0 || num_views > plain.size()) return false;
  for (size_t v = 0; v < num_views; ++v) {
    for (size_t i = 0; i < message.size(); ++i) {
      const float logit = plain[v][i];
      if (!Reads(logit, message[i]) || (message[i] ? logit : -logit) < margin) {
        return false;
      }
    }
  }
  return true;
}

bool DistortionChoice::Review(
    size_t k, int64_t iteration, const Bits& message,
    const std::vector<std::vector<float>>& plain,
    const std::vector<std::vector<float>>& distorted) {
  if (k >= candidates_.size() || plain.empty() || distorted.empty() ||
      distorted.size() % plain.size() != 0) {
    Fail("distortion review: candidate or camera count out of range");
  }
  DistortionCandidate& c = candidates_[k];
  c.broken_bits = 0;
  c.read_bits = 0;
  c.weakest = std::numeric_limits<double>::infinity();
  c.reviewed_at = iteration;
  for (size_t j = 0; j < distorted.size(); ++j) {
    const size_t v = j % plain.size();
    for (size_t i = 0; i < message.size(); ++i) {
      const float through = distorted[j][i];
      const bool read = Reads(plain[v][i], message[i]);
      c.read_bits += read;
      c.broken_bits += read && !Reads(through, message[i]);
      c.weakest = std::min(c.weakest, double(message[i] ? through : -through));
    }
  }
  const bool short_of_it = c.broken_bits > kBrokenShare * c.read_bits;
  c.short_reviews = short_of_it ? c.short_reviews + 1 : 0;
  if (c.simulated() || c.short_reviews < kShortReviews) return false;
  c.since = iteration;
  return true;
}

std::string DistortionChoice::Summary(int64_t last_iteration) const {
  std::string text;
  char part[160];
  for (const DistortionCandidate& c : candidates_) {
    const std::string name = ToString(c.spec);
    if (c.simulated() && last_iteration >= 0 && c.since >= last_iteration) {
      std::snprintf(part, sizeof(part),
                    "%s short at the last check (iteration %lld): never "
                    "simulated",
                    name.c_str(), static_cast<long long>(c.since));
    } else if (c.simulated()) {
      std::snprintf(part, sizeof(part), "%s from iteration %lld", name.c_str(),
                    static_cast<long long>(c.since));
    } else if (c.reviewed_at < 0) {
      std::snprintf(part, sizeof(part),
                    "%s not reviewed (the check views never read)",
                    name.c_str());
    } else if (c.short_reviews > 0) {
      std::snprintf(part, sizeof(part),
                    "%s short at the latest review only (simulated after %d "
                    "in a row)",
                    name.c_str(), kShortReviews);
    } else {
      std::snprintf(part, sizeof(part), "%s not needed", name.c_str());
    }
    text += text.empty() ? "" : "; ";
    text += part;
    if (c.reviewed_at >= 0) {
      std::snprintf(part, sizeof(part),
                    " (at iteration %lld through it: %d of %d read bits "
                    "broken, weakest %+.2f)",
                    static_cast<long long>(c.reviewed_at), c.broken_bits,
                    c.read_bits, c.weakest);
      text += part;
    }
  }
  return text.empty() ? "no candidate layers" : text;
}

std::vector<int64_t> DistortionChoice::State() const {
  std::vector<int64_t> state;
  for (const DistortionCandidate& c : candidates_) {
    state.push_back(c.since);
    state.push_back(c.short_reviews);
  }
  return state;
}

bool DistortionChoice::Restore(const std::vector<int64_t>& state) {
  if (state.size() != 2 * candidates_.size()) return false;
  for (size_t k = 0; k < candidates_.size(); ++k) {
    if (state[2 * k] < -1 || state[2 * k + 1] < 0 ||
        state[2 * k + 1] > std::numeric_limits<int>::max()) {
      return false;
    }
  }
  for (size_t k = 0; k < candidates_.size(); ++k) {
    candidates_[k].since = state[2 * k];
    candidates_[k].short_reviews = int(state[2 * k + 1]);
  }
  return true;
}

}  // namespace watergs
