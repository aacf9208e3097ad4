// How WATER-GS turns several decoded views of one object into one verdict:
// the views' logits are averaged into one recovered message, which is tested
// against the claim (binomial p-value, verdict). Shared by `extract` (renders
// of a 3D model) and `detect` (image files: screenshots, frames, photos of a
// screen), so that both give the same verdict for the same logits.
#pragma once

#include <vector>

#include "watermark/extractor.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace watergs {

// Distribution of the single-view BER (bit errors / L) over views.
struct ViewBerSpread {
  double mean = 0, median = 0, p90 = 0, min = 0, max = 0;
};

// The spread of `view_ber` (any order; empty: all zero). p90 is the
// nearest-rank 90th percentile: the ceil(0.9 n)-th smallest.
ViewBerSpread SpreadOfViewBer(std::vector<double> view_ber);

// Aggregates decoded views (name and `num_bits` logits each) exactly as
// ExtractWatermark does: mean logits (float, summed in view order, each
// divided by the number of views), recovered bits (mean logit > 0), and,
// given `expected` (may be null), each view's bit errors, the recovered
// message's bit errors, BER, p-value, verdict under `thresholds` and the
// spread (mean, median, p90, min, max) of the views' BER. Error (one line) if
// `views` is empty, a view has another number of logits, or `expected` another
// length.
ExtractionResult AggregateViews(std::vector<ViewDecode> views, int num_bits,
                                const Bits* expected,
                                const VerificationThresholds& thresholds);

// The spread of a result's per-view BER (views with bit errors only).
ViewBerSpread SpreadOfViewBer(const ExtractionResult& result);

}  // namespace watergs
