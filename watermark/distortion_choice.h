// Which 3D distortion layers an embedding simulates, chosen per scene
// (embed --distortions auto). Each layer costs fidelity on every scene
// (1.1-1.8 dB from the raw renders, docs/history.md) but buys robustness
// only where the scene's reading is short of it: the embedding starts with
// the plain render and, at each check once every bit of the check views
// reads past the message term's margin (the plain embedding has done its
// work there), renders the check cameras (views and free viewpoints)
// through kReviewDraws draws of each candidate layer; a candidate that
// breaks more than kBrokenShare of the bits the plain render reads (over
// every draw) at kShortReviews reviews in a row is simulated from then on.
// A bit or two broken is left to the views' aggregation; several draws
// because one crop of the file may cut the scene's centre where the next
// cuts nothing seen; reviews in a row because the margins keep growing
// after the check views first read (on horns crop broke 26 of 384 bits at
// that first review, none at the end of a run without layers).
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "distortion/distortion_layer.h"
#include "watermark/message.h"

namespace watergs {

// Share of the plainly read bits a layer may break without being simulated.
constexpr double kBrokenShare = 0.01;
// Draws of each candidate layer per review.
constexpr int kReviewDraws = 4;
// Reviews in a row a layer must fall short at before it is simulated.
constexpr int kShortReviews = 2;

// One candidate layer and what its reviews found.
struct DistortionCandidate {
  DistortionSpec spec;
  // Iteration of the review that turned it on; -1 while it is off.
  int64_t since = -1;
  // At the latest review, over every check camera and draw: bits read by
  // the plain render and lost through the layer, and the weakest signed
  // logit through it (negative when some bit reads wrong).
  int broken_bits = 0, read_bits = 0;
  double weakest = std::numeric_limits<double>::infinity();
  int64_t reviewed_at = -1;
  // Reviews in a row, up to the latest, that found it short.
  int short_reviews = 0;
  bool simulated() const { return since >= 0; }
};

class DistortionChoice {
 public:
  // The identity in `candidates` is dropped: the plain render always stays.
  explicit DistortionChoice(const std::vector<DistortionSpec>& candidates);

  // The layers to sample now: the identity, then each candidate turned on.
  std::vector<DistortionSpec> Simulated() const;
  const std::vector<DistortionCandidate>& candidates() const {
    return candidates_;
  }

  // Whether reviews can judge the layers yet: every bit of every one of the
  // `num_views` first cameras' plain logits reads at least `margin` past
  // zero (the check views; the free viewpoints after them may miss bits).
  static bool Ready(const std::vector<std::vector<float>>& plain,
                    size_t num_views, const Bits& message, double margin);
  // Records candidate k's review at `iteration` from the plain logits per
  // check camera and the logits through draws of the layer (draw d of
  // camera v at distorted[d * plain.size() + v]); turns it on when the draws
  // break more than kBrokenShare of the bits the plain render reads at the
  // kShortReviews-th review in a row. Returns true if it was turned on now.
  // (A check where reviews cannot judge, Ready false, leaves the count.)
  bool Review(size_t k, int64_t iteration, const Bits& message,
              const std::vector<std::vector<float>>& plain,
              const std::vector<std::vector<float>>& distorted);

  // Per candidate: simulated from which iteration, not needed, or never
  // reviewed, with the latest review's figures. Given the run's last
  // iteration, a layer turned on there is said to be short but never
  // simulated.
  std::string Summary(int64_t last_iteration = -1) const;
  // For a checkpoint: per candidate its turned-on iteration and its short
  // reviews in a row. Restore refuses (false) a list of another length or
  // with values out of range.
  std::vector<int64_t> State() const;
  bool Restore(const std::vector<int64_t>& state);

 private:
  std::vector<DistortionCandidate> candidates_;
};

}  // namespace watergs
