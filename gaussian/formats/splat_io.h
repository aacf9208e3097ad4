// antimatter15's .splat format (github.com/antimatter15/splat): no header,
// 32 bytes a Gaussian: position (3 float32), scale (3 float32, linear, not
// log), colour RGBA (4 uint8: SH DC as 0.5 + C0 * dc, alpha = sigmoid of the
// opacity), rotation (4 uint8, w x y z, q / |q| * 128 + 128). No SH above
// degree 0. Little-endian.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>

#include "gaussian/gaussian_model.h"

namespace watergs {

// Decodes the bytes of a .splat file (SH degree 0 model). Throws
// Error("<name>: <problem>") for an empty file, a size that is not a
// multiple of 32, or a position or scale that is NaN, infinite or (scale)
// negative. A scale of exactly 0 (log -Inf) is read as kLogScaleFloor; how
// many were replaced is returned in `replaced` (the caller warns). Alphas 0
// and 255 give logits -+kOpacityLogitLimit.
GaussianModel DecodeSplat(const std::string& name, const uint8_t* data,
                          size_t size, size_t* replaced = nullptr);

// Encodes a model as splat-transform writes .splat (antimatter15's own
// converter does the same): colour, alpha and rotation bytes truncated,
// not rounded; SH above degree 0 dropped. Throws Error for a non-finite
// value.
std::string EncodeSplat(const GaussianModel& model);

// Writes EncodeSplat(model) to `path` atomically.
void WriteSplat(const std::string& path, const GaussianModel& model);

}  // namespace watergs
