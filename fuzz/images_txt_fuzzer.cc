// libFuzzer target: COLMAP images.txt (see colmap_fuzzer.h).
#include "fuzz/colmap_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return watergs::fuzz::FuzzColmapFile(watergs::fuzz::ColmapFile::kImages,
                                       watergs::ModelFormat::kText, data, size);
}
