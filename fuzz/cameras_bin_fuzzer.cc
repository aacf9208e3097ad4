// libFuzzer target: COLMAP cameras.bin (see colmap_fuzzer.h).
#include "fuzz/colmap_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return watergs::fuzz::FuzzColmapFile(watergs::fuzz::ColmapFile::kCameras,
                                       watergs::ModelFormat::kBinary, data,
                                       size);
}
