// PlayCanvas's compressed PLY (SuperSplat, splat-transform's
// `.compressed.ply`): a binary little-endian PLY with three elements.
//   chunk:  one per 256 Gaussians, float min/max of x y z, of the log-scales
//           (min_scale_x ...), and optionally of the colours (min_r ...,
//           colour = 0.5 + C0 * SH DC; files without them store colour
//           directly in [0, 1]);
//   vertex: uint packed_position and packed_scale (11-10-11 bits, x in the
//           high bits, unit-interval within the chunk's range),
//           packed_rotation (2 bits: index of the largest component of
//           rot_0..3, then the other three in 10 bits each as
//           (v / sqrt(2)) + 0.5), packed_color (8-8-8-8: r g b within the
//           chunk's range, then alpha = sigmoid of the opacity);
//   sh:     optional, uchar f_rest_0..K-1 (K = 9, 24, 45; channel-major as
//           in Inria's PLY), (v / 8 + 0.5) * 256 truncated.
// The writer sorts the Gaussians in Morton order first, as splat-transform
// does, so that each chunk of 256 covers a small region.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"

namespace watergs {

// Gaussians per chunk.
constexpr size_t kCompressedPlyChunk = 256;

// True if the text up to end_header of a PLY declares an element `chunk`
// (what tells a compressed PLY from a plain one).
bool IsCompressedPlyHeader(const uint8_t* data, size_t size);

// Decodes a compressed PLY's bytes. Throws Error("<name>: <problem>") for a
// header that is not the compressed schema (format, elements, property
// names and types), counts that disagree (chunks != ceil(vertices / 256),
// sh rows != vertices), a size other than the one the header implies
// (truncated or trailing data) and NaN/Inf chunk ranges. Alphas 0 and 255
// give logits -+kOpacityLogitLimit (splat-transform decodes them to -+Inf).
GaussianModel DecodeCompressedPly(const std::string& name, const uint8_t* data,
                                  size_t size);

// Encodes a model as splat-transform does: Morton order, per-chunk ranges
// (log-scale ranges clamped to [-20, 20]), colour ranges included, SH
// above degree 0 as uchar. order[i] is the index in `model` of the file's
// Gaussian i. Throws Error for a non-finite value.
std::string EncodeCompressedPly(const GaussianModel& model,
                                std::vector<uint32_t>* order = nullptr);

// Writes EncodeCompressedPly(model) to `path` atomically.
void WriteCompressedPly(const std::string& path, const GaussianModel& model);

// Indices of the Gaussians in splat-transform's Morton order: positions
// quantised to 10 bits per axis over their bounding box, sorted by the
// interleaved code, runs of more than 256 equal codes sorted again within
// their own box.
std::vector<uint32_t> MortonOrder(const GaussianModel& model);

}  // namespace watergs
