// Format detection and the one model loader (see model_io.h).
#include "gaussian/formats/model_io.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/formats/sog_io.h"
#include "gaussian/formats/splat_io.h"
#include "gaussian/formats/spz_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

// Bytes read to tell the formats apart: a compressed PLY's header is ~1 KB.
constexpr size_t kSniffBytes = 1 << 16;

std::vector<uint8_t> ReadPrefix(const std::string& path, size_t n) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) FailAt(path, "file not found");
  if (std::filesystem::is_directory(path, ec)) {
    FailAt(path, "is a directory, expected a model file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) FailAt(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<uint8_t> bytes(n);
  in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(n));
  bytes.resize(size_t(in.gcount()));
  return bytes;
}

bool StartsWith(const std::vector<uint8_t>& bytes, const char* prefix) {
  const size_t n = std::strlen(prefix);
  return bytes.size() >= n && std::memcmp(bytes.data(), prefix, n) == 0;
}

bool EndsWith(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) return false;
  return std::equal(suffix.rbegin(), suffix.rend(), text.rbegin(),
                    [](char a, char b) {
                      return std::tolower(static_cast<unsigned char>(a)) ==
                             std::tolower(static_cast<unsigned char>(b));
                    });
}

}  // namespace

const char* GaussianFormatName(GaussianFormat format) {
  switch (format) {
    case GaussianFormat::kPly:
      return "ply";
    case GaussianFormat::kCompressedPly:
      return "compressed_ply";
    case GaussianFormat::kSpz:
      return "spz";
    case GaussianFormat::kSplat:
      return "splat";
    case GaussianFormat::kSog:
      return "sog";
  }
  return "?";
}

GaussianFormat DetectGaussianFormat(const std::string& path) {
  const std::vector<uint8_t> head = ReadPrefix(path, kSniffBytes);
  if (StartsWith(head, "ply\n") || StartsWith(head, "ply\r\n")) {
    return IsCompressedPlyHeader(head.data(), head.size())
               ? GaussianFormat::kCompressedPly
               : GaussianFormat::kPly;
  }
  if (StartsWith(head, "\x1f\x8b") || StartsWith(head, "NGSP")) {
    return GaussianFormat::kSpz;  // DecodeSpz names what it is not
  }
  if (StartsWith(head, "PK\x03\x04")) {
    return GaussianFormat::kSog;  // DecodeSog names what it is not
  }
  if (LooksLikeSogMeta(head.data(), head.size())) return GaussianFormat::kSog;
  // .splat has no header; text of the right size must not pass for one (a
  // real record's colour and rotation bytes are rarely all printable).
  const bool text =
      !head.empty() && std::all_of(head.begin(), head.end(), [](uint8_t c) {
        return (c >= 0x20 && c < 0x7f) || c == '\n' || c == '\r' || c == '\t';
      });
  if (text) {
    FailAt(path,
           "a text file, not a 3DGS model (PLY, compressed PLY, .spz, "
           ".splat, SOG or its meta.json)");
  }
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) FailAt(path, "cannot read file size: " + ec.message());
  if (size > 0 && size % 32 == 0) return GaussianFormat::kSplat;
  FailAt(path,
         "not a 3DGS model: not PLY (no 'ply' line), not SPZ (no gzip "
         "signature), and " +
             std::to_string(size) +
             " bytes is not a multiple of the 32-byte .splat record");
}

ModelData ReadModelFile(const std::string& path,
                        const PlyReadOptions& options) {
  ModelData data;
  data.format = DetectGaussianFormat(path);
  if (data.format == GaussianFormat::kPly) {
    static_cast<PlyData&>(data) = ReadPly(path, options);
    data.format_detail = "PLY";
    return data;
  }
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  data.file_size = bytes.size();
  size_t replaced = 0;
  switch (data.format) {
    case GaussianFormat::kCompressedPly:
      data.model = DecodeCompressedPly(path, bytes.data(), bytes.size());
      data.format_detail = "PlayCanvas compressed PLY";
      break;
    case GaussianFormat::kSpz: {
      SpzInfo info;
      try {
        data.model = DecodeSpz(path, bytes.data(), bytes.size(), &info);
      } catch (const Error& spz_error) {
        // A .splat whose first position's low bytes happen to be 1f 8b
        // (1 in 65536) reads as .splat; if it does not, the SPZ error is
        // the one that tells what is wrong.
        if (bytes.size() % 32 != 0 || bytes[0] != 0x1f) throw;
        try {
          data.model = DecodeSplat(path, bytes.data(), bytes.size(), &replaced);
        } catch (const Error&) {
          throw spz_error;
        }
        data.format = GaussianFormat::kSplat;
        data.format_detail = "antimatter15 .splat";
        break;
      }
      data.format_detail = "SPZ version " + std::to_string(info.version) +
                           " (" + std::to_string(info.fractional_bits) +
                           " fractional bits" +
                           (info.antialiased ? ", antialiased" : "") + ")";
      break;
    }
    case GaussianFormat::kSplat:
      data.model = DecodeSplat(path, bytes.data(), bytes.size(), &replaced);
      data.format_detail = "antimatter15 .splat";
      break;
    case GaussianFormat::kSog: {
      SogInfo info;
      const bool zip = bytes.size() >= 2 && bytes[0] == 'P' && bytes[1] == 'K';
      data.model = zip ? DecodeSog(path, bytes.data(), bytes.size(), &info)
                       : ReadSogMeta(path, &info);
      data.format_detail =
          std::string("PlayCanvas SOG") + (zip ? " (bundled" : " (meta.json") +
          (info.palette_size
               ? ", SH palette of " + std::to_string(info.palette_size)
               : std::string(", no SH bands")) +
          (info.generator.empty() ? "" : ", written by " + info.generator) +
          ")";
      break;
    }
    case GaussianFormat::kPly:
      break;
  }
  // The decoders produce only finite values; a broken invariant must not
  // reach training or rendering.
  if (data.model.CountNonFinite() > 0) {
    FailAt(path, "decoded model holds NaN/Inf values");
  }
  data.layout = InriaPlyLayout(data.model.sh_degree, data.model.size());
  data.replaced_infinities = replaced;
  WarnInfinitiesReplaced(path, replaced, options.warnings);
  return data;
}

GaussianFormat OutputFormatForPath(const std::string& path) {
  if (EndsWith(path, ".compressed.ply")) return GaussianFormat::kCompressedPly;
  if (EndsWith(path, ".spz")) return GaussianFormat::kSpz;
  if (EndsWith(path, ".splat")) return GaussianFormat::kSplat;
  if (EndsWith(path, ".sog")) return GaussianFormat::kSog;
  return GaussianFormat::kPly;
}

void WriteModelFile(const std::string& path, const GaussianModel& model,
                    const PlyLayout& layout) {
  switch (OutputFormatForPath(path)) {
    case GaussianFormat::kPly:
      return WritePly(path, model, layout);
    case GaussianFormat::kCompressedPly:
      return WriteCompressedPly(path, model);
    case GaussianFormat::kSpz:
      return WriteSpz(path, model);
    case GaussianFormat::kSplat:
      return WriteSplat(path, model);
    case GaussianFormat::kSog:
      return WriteSog(path, model);
  }
}

}  // namespace watergs
