// libFuzzer target: COLMAP images.bin (see colmap_fuzzer.h).
#include "fuzz/colmap_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return watergs::fuzz::FuzzColmapFile(watergs::fuzz::ColmapFile::kImages,
                                       watergs::ModelFormat::kBinary, data,
                                       size);
}
