// Hard-viewpoint replay for the embedding: a fixed set of free viewpoints
// the fine-tuning returns to in proportion to how far each still is from
// reading every bit past the margin. Uniformly sampled viewpoints spend most
// iterations on views that already read; the few that do not (close-ups of
// blurred surfaces from inside a capture ring) set the single-view tail.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "gaussian/camera.h"
#include "watermark/message.h"

namespace watergs {

// How far one view's logits (> 0 reads bit 1) fall short of reading
// `message` past `margin`: the sum over bits of max(0, margin - s), s the
// logit signed towards the message bit. 0 once every bit reads past it.
double MarginDeficit(const std::vector<float>& logits, const Bits& message,
                     double margin);

class ViewpointPool {
 public:
  // Every view starts with the same weight (nothing measured yet).
  explicit ViewpointPool(std::vector<RenderCamera> cameras);

  size_t size() const { return cameras_.size(); }
  const RenderCamera& camera(size_t k) const { return cameras_[k]; }

  // Records view k's deficit (MarginDeficit); finite and >= 0.
  void SetDeficit(size_t k, double deficit);
  const std::vector<double>& deficits() const { return deficits_; }
  // Replaces every deficit (a checkpoint's); false if the count differs or
  // any is negative or not finite.
  bool RestoreDeficits(const std::vector<double>& deficits);

  // Views still short of the margin.
  size_t NumShort() const;
  // A view drawn with probability proportional to its deficit; -1 when every
  // view reads past the margin.
  int Sample(std::mt19937_64* rng) const;

 private:
  std::vector<RenderCamera> cameras_;
  std::vector<double> deficits_;
};

}  // namespace watergs
