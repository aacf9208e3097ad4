// Versioned binary container for network weights and training checkpoints.
//
// Layout (all integers little-endian, version 1):
//   magic        8 bytes  "WGSNNET\0"
//   version      u32      1
//   kind         u32 length + bytes   ("hidden-model", "hidden-checkpoint")
//   meta count   u32, then per entry: u32 length + key bytes, i64 value
//                (architecture: num_bits, channels, encoder_blocks, ...)
//   tensor count u32, then per tensor: u32 length + name bytes, u32 rank,
//                rank x i32 dims, prod(dims) x f32 values
//   checksum     u64      FNV-1a 64 of every byte before it
// Readers refuse a wrong magic, an unknown version, a checksum mismatch and
// any truncation with one-line errors naming the file.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace watergs {

// One stored tensor.
struct TensorRecord {
  // Parameter name, e.g. "decoder.block0.conv.weight".
  std::string name;
  // Dimensions, outermost first.
  std::vector<int> shape;
  // prod(shape) values, row-major.
  std::vector<float> values;
};

struct NetworkFile {
  // What the file holds, e.g. "hidden-model".
  std::string kind;
  // Integer facts (architecture, training counters), in file order.
  std::vector<std::pair<std::string, int64_t>> meta;
  // Weights and buffers, in file order.
  std::vector<TensorRecord> tensors;

  // Value of `key`; throws Error("<path>: missing field key") if absent.
  int64_t Meta(const std::string& key, const std::string& path) const;
  // Tensor called `name`, or null.
  const TensorRecord* Find(const std::string& name) const;
};

// Version 2 files end with the standard FNV-1a 64 checksum (Fnv1a64,
// gaussian/util/file_util.h) of the bytes before it; version 1 files (written
// before 2026-11-27) with FNV-1a from an offset basis one digit short
// (1469598103934665603), still read.
inline constexpr uint32_t kNetworkFileVersion = 2;

// The file's bytes, checksum included.
std::string SerializeNetworkFile(const NetworkFile& file);
// Parses bytes read from `path` (named in errors).
NetworkFile ParseNetworkFile(const std::string& path,
                             const std::vector<uint8_t>& bytes);

// Atomic write / checked read of a network file.
void WriteNetworkFile(const std::string& path, const NetworkFile& file);
NetworkFile ReadNetworkFile(const std::string& path);

}  // namespace watergs
