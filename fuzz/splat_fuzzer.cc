// libFuzzer target: the antimatter15 .splat reader
// (gaussian/formats/splat_io.h). A file that reads must hold only finite
// values, and encoding it must give a file of the same size that reads again.
#include "fuzz/fuzz_support.h"
#include "gaussian/formats/splat_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string name = "fuzz.splat";
  GaussianModel model;
  try {
    model = DecodeSplat(name, data, size);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, name);
    return 0;
  }
  if (model.CountNonFinite() > 0) fuzz::Finding(".splat decoded to NaN/Inf");
  try {
    const std::string again = EncodeSplat(model);
    if (again.size() != size)
      fuzz::Finding(".splat re-encoded to another size");
    const GaussianModel reread = DecodeSplat(
        name, reinterpret_cast<const uint8_t*>(again.data()), again.size());
    // Positions are float32 in both: bit for bit the same.
    if (reread.means != model.means) {
      fuzz::Finding(".splat positions changed on encode and decode");
    }
  } catch (const Error& e) {
    fuzz::Finding(std::string("a decoded .splat cannot be encoded again: ") +
                  e.what());
  }
  return 0;
}
