// libFuzzer target: the LPIPS-VGG weights file (watermark/lpips.h), the path
// `watergs eval --lpips_weights` takes. The trailing CRC-32 is recomputed so
// that mutations reach the tensor parser behind it.
#include <zlib.h>

#include <cstring>

#include "fuzz/fuzz_support.h"
#include "watermark/lpips.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  std::vector<uint8_t> bytes(data, data + size);
  if (bytes.size() >= 4) {
    const size_t body = bytes.size() - 4;
    const uint32_t crc = uint32_t(crc32(0L, bytes.data(), uInt(body)));
    std::memcpy(bytes.data() + body, &crc, 4);
  }
  const std::string path =
      fuzz::WriteScratchFile("lpips_vgg.bin", bytes.data(), bytes.size());
  try {
    Lpips::Load(path);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, path);
  }
  return 0;
}
