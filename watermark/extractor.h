// WATER-GS watermark extraction and verification: renders a model from some
// viewpoints, decodes each render with the frozen decoder, averages the
// logits over views into one recovered message and, given the claimed
// message, tests it against the null hypothesis of an unmarked model
// (binomial p-value, verdict at a documented false-positive rate).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace watergs {

// One decoded view.
struct ViewDecode {
  // View name (workspace image name or "free_<k>").
  std::string name;
  // L logits of this view's render.
  std::vector<float> logits;
  // Bit errors against the expected message (-1 without one).
  int bit_errors = -1;
};

struct ExtractionResult {
  // Mean logits over views and the bits they read (logit > 0 -> 1).
  std::vector<float> mean_logits;
  Bits recovered;
  // Per view.
  std::vector<ViewDecode> views;
  // Against the expected message (only when one was given).
  bool has_expected = false;
  Bits expected;
  int bit_errors = 0;
  double ber = 0;
  // Single views: the distribution of each view's own BER (what one
  // screenshot reads), next to the aggregate above. p90: nearest rank.
  double min_view_ber = 0, median_view_ber = 0, max_view_ber = 0;
  double mean_view_ber = 0, p90_view_ber = 0;
  // P[at least this many matching bits | unmarked model].
  double p_value = 1;
  Verdict verdict = Verdict::kInconclusive;
  VerificationThresholds thresholds;
};

// The camera a fraction t of the way from a to b: position linear,
// orientation slerp, a's intrinsics.
RenderCamera InterpolateCameras(const RenderCamera& a, const RenderCamera& b,
                                double t);

// n viewpoints, each between two of `train_views` (indices into `views`; a
// random pair, a random fraction), drawn from `seed`: the embedder's check
// viewpoints and hard-viewpoint pool.
std::vector<RenderCamera> SampleViewpointsBetween(
    const TrainingViews& views, const std::vector<size_t>& train_views, int n,
    uint64_t seed);

// `n` viewpoints between the cameras of `views`: each interpolates position
// (linearly) and orientation (slerp) between two random cameras at a random
// fraction, keeping the first one's intrinsics. Deterministic for a seed.
std::vector<RenderCamera> SampleFreeViewpoints(const TrainingViews& views,
                                               int n, uint64_t seed);

// An attack on each render before it is decoded (JPEG, resize, ...).
using RenderAttack = std::function<ImageRGB(const ImageRGB&)>;

// Sees each camera's index and the image the decoder read (after the attack),
// so that callers measure those images without rendering them again.
using DecodedViewObserver =
    std::function<void(size_t camera, const ImageRGB& decoded)>;

// Renders `model` from each camera (whole frames, clamped to [0, 1]), decodes
// and aggregates; `expected` (may be null) must have the decoder's length.
// `attack`, when set, transforms each clamped render before decoding;
// `observe`, when set, sees each decoded image.
ExtractionResult ExtractWatermark(Rasterizer& rasterizer,
                                  const GaussianModel& model,
                                  const std::vector<RenderCamera>& cameras,
                                  const std::vector<std::string>& names,
                                  BitDecoder& decoder, const Bits* expected,
                                  const std::array<float, 3>& background,
                                  const VerificationThresholds& thresholds,
                                  const RenderAttack& attack = {},
                                  const DecodedViewObserver& observe = {});

// The owner's reading: each bit from logit(suspect) - logit(reference) at
// the same viewpoint, the reference being the unwatermarked model the owner
// keeps: the scene's own lean per bit cancels. A difference within
// kOwnerTieLogit of zero reads neither bit: against `expected` it counts as
// an error (so the reference itself reads no bit right and is "absent"),
// without one it reads 0.
constexpr float kOwnerTieLogit = 1e-3f;

// Resolves the ties of a difference of logits as above, in place.
void ResolveOwnerTies(std::vector<float>* difference, const Bits* expected);

// Per view, suspect minus reference logits (same order and names), ties
// resolved as above. Error if the lists differ in length or logit count.
std::vector<ViewDecode> DifferenceViews(
    std::vector<ViewDecode> suspect, const std::vector<ViewDecode>& reference,
    const Bits* expected);

// Both readings of the same renders.
struct OwnerExtraction {
  ExtractionResult blind;  // the suspect's logits alone (ExtractWatermark)
  ExtractionResult owner;  // their difference from the reference's
};

// ExtractWatermark of `model`, and the owner's reading against `reference`
// rendered from the same cameras and sent through the same `attack` (as
// detect sends the raw render the way the suspect image went: what a JPEG
// does to any render of the scene then cancels; docs/history.md,
// "Screenshots: registration and the reference"), or from
// `reference_cameras` when given (one per camera: a suspect moved by a
// similarity is rendered from moved cameras, the raw model from the
// original ones).
OwnerExtraction ExtractWatermarkWithReference(
    Rasterizer& rasterizer, const GaussianModel& model,
    const GaussianModel& reference, const std::vector<RenderCamera>& cameras,
    const std::vector<std::string>& names, BitDecoder& decoder,
    const Bits* expected, const std::array<float, 3>& background,
    const VerificationThresholds& thresholds, const RenderAttack& attack = {},
    const DecodedViewObserver& observe = {},
    const std::vector<RenderCamera>& reference_cameras = {});

// The result as JSON text (recovered hex/bits, BER, spread, p-value, verdict,
// per-view BER).
std::string ExtractionToJson(const ExtractionResult& result);

}  // namespace watergs
