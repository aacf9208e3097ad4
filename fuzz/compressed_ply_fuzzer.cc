// libFuzzer target: the PlayCanvas compressed PLY reader
// (gaussian/formats/compressed_ply_io.h). A file that reads must hold only
// finite values and must encode and decode again to as many Gaussians of the
// same SH degree.
#include "fuzz/fuzz_support.h"
#include "gaussian/formats/compressed_ply_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string name = "fuzz.compressed.ply";
  GaussianModel model;
  try {
    model = DecodeCompressedPly(name, data, size);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, name);
    return 0;
  }
  if (model.CountNonFinite() > 0) {
    fuzz::Finding("compressed PLY decoded to NaN/Inf");
  }
  try {
    const std::string again = EncodeCompressedPly(model);
    const GaussianModel reread = DecodeCompressedPly(
        name, reinterpret_cast<const uint8_t*>(again.data()), again.size());
    if (reread.size() != model.size() || reread.sh_degree != model.sh_degree) {
      fuzz::Finding("compressed PLY model changed shape on encode and decode");
    }
  } catch (const Error& e) {
    fuzz::Finding(
        std::string("a decoded compressed PLY cannot be encoded again: ") +
        e.what());
  }
  return 0;
}
