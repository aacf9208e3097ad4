// PlayCanvas's SOG (developer.playcanvas.com/user-manual/gaussian-splatting/
// formats/sog), meta.json version 2: the Gaussians as lossless WebP images,
// one pixel a Gaussian in row-major order, and a meta.json naming them.
//   means_l, means_u: x y z as 16 bits (low and high byte) between the
//                     meta's mins and maxs of sign(v) * ln(|v| + 1);
//   quats:            the three smallest components of the unit quaternion
//                     (w x y z order, largest made positive) as
//                     (c * sqrt(2) + 1) / 2 in 8 bits, alpha 252 + the index
//                     of the largest;
//   scales:           three indices into a 256-entry codebook of log-scales;
//   sh0:              three indices into a codebook of SH DC values, alpha
//                     the 8-bit sigmoid of the opacity;
//   shN (optional):   a palette of `count` SH vectors (shN_centroids: 64 a
//                     row, one pixel a coefficient, rgb indices into its own
//                     codebook) and a 16-bit label per Gaussian (shN_labels,
//                     red low byte, green high byte).
// A bundled .sog is a ZIP of those files; an unbundled one is the meta.json
// with the images beside it. The axes are the PLY's (splat-transform 2.x
// writes SOG in the PLY's frame), so no axis flip is applied.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"

namespace watergs {

struct SogInfo {
  // True for a ZIP (.sog), false for a meta.json with its images.
  bool bundled = false;
  // Palette size of the higher SH bands (0 without them).
  size_t palette_size = 0;
  // The meta's asset.generator, if any (e.g. "splat-transform v2.7.1").
  std::string generator;
};

// True if the bytes look like a SOG meta.json: a JSON object whose text
// names "means" and "quats" (the caller then decodes it and gets the
// reasons for anything wrong).
bool LooksLikeSogMeta(const uint8_t* data, size_t size);

// Decodes a bundled .sog (the ZIP's bytes). Throws Error("<name>: <problem>")
// for a ZIP that is corrupt or truncated, a missing member, a meta.json that
// is not version 2 or lacks a field, an image that is not a WebP or is
// smaller than the count needs, a codebook index out of range, non-finite
// codebook or range values, or positions beyond float. Alphas 0 and 255
// give logits -+kOpacityLogitLimit.
GaussianModel DecodeSog(const std::string& name, const uint8_t* data,
                        size_t size, SogInfo* info = nullptr);

// Decodes a SOG from the text of its meta.json and `load`, which returns the
// bytes of a file the meta names (and throws Error if it cannot); errors as
// DecodeSog's.
GaussianModel DecodeSogFiles(
    const std::string& name, const std::string& meta_text,
    const std::function<std::string(const std::string&)>& load,
    SogInfo* info = nullptr);

// Decodes an unbundled SOG: the text of `meta_path` and the images it names,
// read from its folder (plain file names only: no folders, no "..").
GaussianModel ReadSogMeta(const std::string& meta_path,
                          SogInfo* info = nullptr);

struct SogWriteOptions {
  // Rounds of k-means for the SH palette (splat-transform's default is 10).
  int palette_iterations = 10;
  // libwebp's lossless effort, 0 (fastest) to 6; the same pixels at any
  // effort, only the file size changes.
  int webp_method = 4;
};

// Encodes a model as a bundled .sog, as splat-transform 2.7.1 does: Morton
// order, images of width ceil(sqrt(n) / 4) * 4, 256-entry codebooks for
// scales, SH DC and the palette's values, a palette of min(65536, the
// largest power of two <= n) SH vectors; means, quaternion and alpha bytes
// truncated, not rounded. order[i] is the index in `model` of the file's
// Gaussian i. Throws Error for a non-finite value.
std::string EncodeSog(const GaussianModel& model,
                      const SogWriteOptions& options = {},
                      std::vector<uint32_t>* order = nullptr);

// Writes EncodeSog(model) to `path` atomically.
void WriteSog(const std::string& path, const GaussianModel& model,
              const SogWriteOptions& options = {});

}  // namespace watergs
