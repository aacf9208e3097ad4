// Random resampling of a render before the decoder reads it, for embedding.
//
// A message steered on the training views' pixel grids rides on patterns the
// decoder's 4x4 pooling grid aligns with; a novel view moves that grid by a
// fraction of a pixel and changes the scale, and those patterns no longer
// read. Decoding each iteration's render through a random sub-pixel shift and
// zoom (expectation over transformation) makes the embedding find a message
// that survives both, which is what a single novel view needs
// (docs/history.md, "One view is enough").
#pragma once

#include <random>

#include "gaussian/image.h"

namespace watergs {

struct DecoderJitterOptions {
  // Largest shift of the sampling grid in input pixels, each axis (0: none).
  double max_shift = 0;
  // The decoder reads the render resized by a factor drawn log-uniformly in
  // [min_scale, max_scale] (1, 1: no resize). min_scale >= 0.5: bilinear
  // sampling below that aliases.
  double min_scale = 1, max_scale = 1;

  bool enabled() const {
    return max_shift > 0 || min_scale != 1 || max_scale != 1;
  }
};

// One draw: out pixel (x, y) samples the input at
// ((x + 0.5) / scale - 0.5 + dx, (y + 0.5) / scale - 0.5 + dy).
struct JitterSample {
  double scale = 1, dx = 0, dy = 0;
  // Output size: the input's scaled and rounded, at least 1.
  int width = 0, height = 0;
};

// Error unless 0 <= max_shift <= 8 and 0.5 <= min_scale <= max_scale <= 2.
void CheckDecoderJitter(const DecoderJitterOptions& options);

// A draw for a width x height input.
JitterSample SampleJitter(const DecoderJitterOptions& options, int width,
                          int height, std::mt19937_64* rng);

// image [h,w,3] -> out [sample.height, sample.width, 3], bilinear with edge
// clamping.
void JitterForward(const ImageRGB& image, const JitterSample& sample,
                   ImageRGB* out);

// The adjoint: adds the gradient of out (grad_out, out's shape) into
// grad_image (the input's shape).
void JitterAdjoint(const ImageRGB& grad_out, const JitterSample& sample,
                   ImageRGB* grad_image);

}  // namespace watergs
