// libFuzzer target: the SOG reader (gaussian/formats/sog_io.h). An input
// starting with "PK" is a bundled .sog (ZIP, CRC-checked); any other is
// meta.json and the images it names, split by kSogFuzzSeparator and handed out
// in the order the decoder asks for them, so that mutations reach the JSON and
// WebP parsers past the ZIP's checksums. A file that reads must hold only
// finite values and (checked on one input in 16) must encode and decode again
// to as many Gaussians of the same SH degree.
#include <cstring>
#include <vector>

#include "fuzz/fuzz_support.h"
#include "gaussian/formats/sog_io.h"

namespace {

std::vector<std::string> SplitParts(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::string separator = watergs::fuzz::kSogFuzzSeparator;
  std::vector<std::string> parts;
  size_t begin = 0;
  for (;;) {
    const size_t end = text.find(separator, begin);
    parts.push_back(text.substr(begin, end - begin));
    if (end == std::string::npos) break;
    begin = end + separator.size();
  }
  return parts;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string name = "fuzz.sog";
  GaussianModel model;
  try {
    if (size >= 2 && data[0] == 'P' && data[1] == 'K') {
      model = DecodeSog(name, data, size);
    } else {
      const std::vector<std::string> parts = SplitParts(data, size);
      size_t next = 1;
      model = DecodeSogFiles(name, parts[0], [&](const std::string& file) {
        if (next >= parts.size()) FailAt(name + ": " + file, "file not found");
        return parts[next++];
      });
    }
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, name);
    return 0;
  }
  if (model.CountNonFinite() > 0) fuzz::Finding("SOG decoded to NaN/Inf");
  // libwebp's encoder costs ~1 ms an image under ASan, ten times the decode:
  // one input in 16 (by its size) is encoded again, so the reader gets the
  // executions.
  if (size % 16 != 0) return 0;
  try {
    // One k-means round and libwebp's fastest effort: the decoder is fuzzed.
    const std::string again = EncodeSog(model, {1, 0});
    const GaussianModel reread = DecodeSog(
        name, reinterpret_cast<const uint8_t*>(again.data()), again.size());
    // An empty model has no SH palette to write: its degree reads as 0.
    if (reread.size() != model.size() ||
        (model.size() > 0 && reread.sh_degree != model.sh_degree)) {
      fuzz::Finding("SOG model changed shape on encode and decode");
    }
  } catch (const Error& e) {
    fuzz::Finding(std::string("a decoded SOG cannot be encoded again: ") +
                  e.what());
  }
  return 0;
}
