// libFuzzer target: decoder/encoder weights files (watermark/network_file.h)
// and the HiDDeN model built from them (watermark/hidden_model.h), the path
// `watergs extract --decoder_path` takes. The trailing checksum is recomputed
// so that mutations reach the parser. A parsed tensor must hold exactly
// prod(shape) values.
#include <algorithm>

#include "fuzz/fuzz_support.h"
#include "gaussian/util/file_util.h"
#include "watermark/hidden_model.h"
#include "watermark/network_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::vector<uint8_t> bytes = fuzz::WithValidChecksum(
      data, size,
      [](const uint8_t* p, size_t n) { return watergs::Fnv1a64(p, n); });
  const std::string path = "decoder.bin";
  NetworkFile file;
  try {
    file = ParseNetworkFile(path, bytes);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, path);
    return 0;
  }
  for (const TensorRecord& tensor : file.tensors) {
    // Saturated at 2^64 (a later 0 dim still gives 0): never wraps.
    const unsigned __int128 kCap = static_cast<unsigned __int128>(1) << 64;
    unsigned __int128 count = 1;
    for (const int d : tensor.shape) {
      if (d < 0) fuzz::Finding("tensor " + tensor.name + " has a negative dim");
      count = std::min(count * static_cast<unsigned>(d), kCap);
    }
    if (count != tensor.values.size()) {
      fuzz::Finding("tensor " + tensor.name +
                    " holds a value count other than prod(shape)");
    }
  }
  try {
    HiddenModelFromFile(path, file, /*need_encoder=*/false);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, path);
  }
  return 0;
}
