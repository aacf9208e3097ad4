// The one loader every command reads a model with: the format is told by
// the file's content (magic bytes and header), never by its extension.
//   "ply\n" header without element chunk  -> Inria-style PLY (ply_io.h)
//   "ply\n" header with element chunk     -> PlayCanvas compressed PLY
//   gzip (1f 8b) holding "NGSP"           -> Niantic .spz, versions 2 and 3
//   "NGSP" (uncompressed)                 -> .spz version 4
//   zip (PK 03 04)                        -> PlayCanvas SOG, bundled
//   JSON naming "means" and "quats"       -> SOG meta.json, images beside it
//   anything else, a multiple of 32 bytes -> antimatter15 .splat
// Other zips, other JSON and gzip of something other than SPZ are refused
// with the reason. Writers pick the format from the output path's extension
// (.spz, .splat, .compressed.ply, .sog; anything else is a PLY).
#pragma once

#include <string>

#include "gaussian/formats/ply_io.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

enum class GaussianFormat { kPly, kCompressedPly, kSpz, kSplat, kSog };

// "ply", "compressed_ply", "spz", "splat", "sog".
const char* GaussianFormatName(GaussianFormat format);

// A model as read from any format. The PlyData part is what ReadPly gives
// for a PLY; for the other formats the layout is Inria's for the model's SH
// degree (what the model is written back as), header_size is 0 and
// non_finite_count is 0 (those readers refuse NaN/Inf).
struct ModelData : PlyData {
  // Format the content was detected as.
  GaussianFormat format = GaussianFormat::kPly;
  // One line on the format, e.g. "SPZ version 3 (12 fractional bits)".
  std::string format_detail;
};

// Format of the file at `path` from its first bytes; throws
// Error("<path>: <problem>") if it is missing, unreadable or none of the
// formats (see the top of this file).
GaussianFormat DetectGaussianFormat(const std::string& path);

// Reads a model in any format. Throws Error("<path>: <problem>") for
// anything it cannot read. Infinite opacity logits and zero scales are read
// as what viewers render, with one warning line on options.warnings (see
// kOpacityLogitLimit); options.allow_non_finite applies to PLY only.
ModelData ReadModelFile(const std::string& path,
                        const PlyReadOptions& options = {});

// The format an output path asks for by its extension (case-insensitive):
// .spz, .splat, .compressed.ply, .sog; anything else is kPly.
GaussianFormat OutputFormatForPath(const std::string& path);

// Writes `model` atomically in the format OutputFormatForPath(path) names;
// a PLY is written in `layout` (see WritePly), the other formats ignore it.
void WriteModelFile(const std::string& path, const GaussianModel& model,
                    const PlyLayout& layout);

}  // namespace watergs
