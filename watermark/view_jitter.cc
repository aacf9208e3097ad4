// Random resampling of a render before decoding (see view_jitter.h).
#include "watermark/view_jitter.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// The two source taps and weights of one output coordinate along an axis of
// `size` input pixels (edge-clamped).
struct Taps {
  int i0, i1;
  float w0, w1;
};

Taps AxisTaps(int out, double scale, double shift, int size) {
  const double s = (out + 0.5) / scale - 0.5 + shift;
  const double f = std::floor(s);
  const double frac = s - f;
  const int i = static_cast<int>(f);
  return Taps{std::clamp(i, 0, size - 1), std::clamp(i + 1, 0, size - 1),
              static_cast<float>(1 - frac), static_cast<float>(frac)};
}

template <typename Visit>
void ForEachTap(const JitterSample& sample, int width, int height,
                Visit visit) {
  std::vector<Taps> xs(sample.width);
  for (int x = 0; x < sample.width; ++x) {
    xs[x] = AxisTaps(x, sample.scale, sample.dx, width);
  }
  for (int y = 0; y < sample.height; ++y) {
    const Taps ty = AxisTaps(y, sample.scale, sample.dy, height);
    for (int x = 0; x < sample.width; ++x) visit(x, y, xs[x], ty);
  }
}

}  // namespace

void CheckDecoderJitter(const DecoderJitterOptions& o) {
  if (!(o.max_shift >= 0 && o.max_shift <= 8)) {
    Fail("decoder jitter: shift must be in [0, 8] pixels");
  }
  if (!(o.min_scale >= 0.5 && o.min_scale <= o.max_scale && o.max_scale <= 2)) {
    Fail("decoder jitter: scales must satisfy 0.5 <= min <= max <= 2");
  }
}

JitterSample SampleJitter(const DecoderJitterOptions& o, int width, int height,
                          std::mt19937_64* rng) {
  std::uniform_real_distribution<double> unit(0, 1);
  JitterSample s;
  const double log_min = std::log(o.min_scale), log_max = std::log(o.max_scale);
  s.scale = std::exp(log_min + (log_max - log_min) * unit(*rng));
  s.dx = o.max_shift * (2 * unit(*rng) - 1);
  s.dy = o.max_shift * (2 * unit(*rng) - 1);
  s.width = std::max(1, static_cast<int>(std::lround(s.scale * width)));
  s.height = std::max(1, static_cast<int>(std::lround(s.scale * height)));
  return s;
}

void JitterForward(const ImageRGB& image, const JitterSample& sample,
                   ImageRGB* out) {
  *out = ImageRGB(sample.width, sample.height);
  ForEachTap(sample, image.width, image.height,
             [&](int x, int y, const Taps& tx, const Taps& ty) {
               const float* a = image.At(tx.i0, ty.i0);
               const float* b = image.At(tx.i1, ty.i0);
               const float* c = image.At(tx.i0, ty.i1);
               const float* d = image.At(tx.i1, ty.i1);
               float* o = out->At(x, y);
               for (int k = 0; k < 3; ++k) {
                 o[k] = ty.w0 * (tx.w0 * a[k] + tx.w1 * b[k]) +
                        ty.w1 * (tx.w0 * c[k] + tx.w1 * d[k]);
               }
             });
}

void JitterAdjoint(const ImageRGB& grad_out, const JitterSample& sample,
                   ImageRGB* grad_image) {
  if (grad_out.width != sample.width || grad_out.height != sample.height) {
    Fail("decoder jitter: gradient of the wrong size");
  }
  ForEachTap(sample, grad_image->width, grad_image->height,
             [&](int x, int y, const Taps& tx, const Taps& ty) {
               const float* g = grad_out.At(x, y);
               float* a = grad_image->At(tx.i0, ty.i0);
               float* b = grad_image->At(tx.i1, ty.i0);
               float* c = grad_image->At(tx.i0, ty.i1);
               float* d = grad_image->At(tx.i1, ty.i1);
               for (int k = 0; k < 3; ++k) {
                 a[k] += ty.w0 * tx.w0 * g[k];
                 b[k] += ty.w0 * tx.w1 * g[k];
                 c[k] += ty.w1 * tx.w0 * g[k];
                 d[k] += ty.w1 * tx.w1 * g[k];
               }
             });
}

}  // namespace watergs
