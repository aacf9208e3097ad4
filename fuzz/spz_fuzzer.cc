// libFuzzer target: the .spz reader (gaussian/formats/spz_io.h), gzip included.
// A file that reads must hold only finite values and must encode and decode
// again to as many Gaussians of the same SH degree.
#include "fuzz/fuzz_support.h"
#include "gaussian/formats/spz_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string name = "fuzz.spz";
  GaussianModel model;
  try {
    model = DecodeSpz(name, data, size);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, name);
    return 0;
  }
  if (model.CountNonFinite() > 0) fuzz::Finding("SPZ decoded to NaN/Inf");
  try {
    const std::string again = EncodeSpz(model);
    const GaussianModel reread = DecodeSpz(
        name, reinterpret_cast<const uint8_t*>(again.data()), again.size());
    if (reread.size() != model.size() || reread.sh_degree != model.sh_degree) {
      fuzz::Finding("SPZ model changed shape on encode and decode");
    }
  } catch (const Error& e) {
    // Positions beyond 2^23 cannot occur: 24-bit input, >= 0 fractional bits.
    fuzz::Finding(std::string("a decoded SPZ cannot be encoded again: ") +
                  e.what());
  }
  return 0;
}
