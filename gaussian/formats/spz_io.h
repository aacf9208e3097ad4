// Niantic's .spz format (github.com/nianticlabs/spz). Versions 2 and 3: a
// gzip stream of a 16-byte header (magic "NGSP", version, count, SH degree,
// fractional bits, flags) and the attributes one after the other. Version 4
// (what splat-transform writes by default): a plaintext 32-byte header, a
// table of contents and each attribute compressed with zstd on its own;
// read, not written. The attributes, in every version: positions
// as 24-bit fixed point, alphas (8-bit sigmoid), colours (8-bit, SH DC * 0.15
// + 0.5), log-scales (8-bit, (s + 10) * 16), rotations (version 2: x y z of
// the w >= 0 quaternion, 8 bits each; version 3: "smallest three", 2 + 3 x 10
// bits, versions 3 and 4) and SH (8 bits, x * 128 + 128, coefficient-major,
// rgb inner).
// The format stores the RUB axes (x right, y up, z back) and 3DGS PLYs the
// RDF axes (y down, z forward): as Niantic's library and PlayCanvas's
// splat-transform 2.x do, the reader turns RUB into RDF and the writer RDF
// into RUB (y and z of positions and quaternions negated, SH coefficients
// signed by their parity), so that PLY -> SPZ -> PLY keeps the scene where
// it was (see docs/formats.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>

#include "gaussian/gaussian_model.h"

namespace watergs {

struct SpzInfo {
  // Header version (2, 3 or 4).
  int version = 0;
  // Fractional bits of the fixed-point positions.
  int fractional_bits = 0;
  // Header flag 0x1: trained with antialiasing (mip-splatting).
  bool antialiased = false;
};

// Decodes the bytes of a .spz file; `name` prefixes every error:
// Error("<name>: <problem>") for data that is neither gzip nor NGSP, a gzip
// or zstd stream that is corrupt or truncated, a header that is not NGSP, a
// version other than 2, 3 or 4, an SH degree above 3, extensions (flag 0x2)
// before version 4 (version 4 skips them), or attribute data other than the
// count needs. Alphas of 0 and 255 give logits of -+kOpacityLogitLimit.
GaussianModel DecodeSpz(const std::string& name, const uint8_t* data,
                        size_t size, SpzInfo* info = nullptr);

struct SpzWriteOptions {
  // 2 (rotations as 3 x 8 bits) or 3 (smallest three, the library default).
  int version = 3;
};

// Encodes a model as the reference library does with its defaults: 12
// fractional bits (fewer when the scene reaches beyond +-2048 units, where
// 12 bits would overflow 24), SH quantised to 5 bits for degree 1 and 4
// bits above. Throws Error for a non-finite value or a version other than 2
// or 3.
std::string EncodeSpz(const GaussianModel& model,
                      const SpzWriteOptions& options = {});

// Writes EncodeSpz(model) to `path` atomically.
void WriteSpz(const std::string& path, const GaussianModel& model,
              const SpzWriteOptions& options = {});

}  // namespace watergs
