// libFuzzer target: the 3DGS PLY reader (gaussian/formats/ply_io.h). A file
// that reads must also be written back in its own layout and read again
// unchanged (binary: model values bit for bit; ascii: same number of
// Gaussians).
#include <cstring>

#include "fuzz/fuzz_support.h"
#include "gaussian/formats/ply_io.h"

namespace {

bool SameFloats(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() ||
          std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

bool SameModel(const watergs::GaussianModel& a,
               const watergs::GaussianModel& b) {
  return a.sh_degree == b.sh_degree && SameFloats(a.means, b.means) &&
         SameFloats(a.log_scales, b.log_scales) &&
         SameFloats(a.quats, b.quats) &&
         SameFloats(a.opacity_logits, b.opacity_logits) &&
         SameFloats(a.sh_dc, b.sh_dc) && SameFloats(a.sh_rest, b.sh_rest);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string path = fuzz::WriteScratchFile("model.ply", data, size);
  PlyData ply;
  try {
    ply = ReadPly(path);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, path);
    return 0;
  }
  const std::string again = fuzz::ScratchDir() + "/again.ply";
  try {
    WritePly(again, ply.model, ply.layout);
    const PlyData reread = ReadPly(again);
    // Ascii values are rewritten in shortest float form, which is exact only
    // through float parsing (the reader parses doubles): compare counts.
    const bool exact = ply.layout.format != PlyFormat::kAscii;
    if (reread.model.size() != ply.model.size() ||
        (exact && !SameModel(ply.model, reread.model))) {
      fuzz::Finding("PLY model changed on write and read back");
    }
  } catch (const Error& e) {
    fuzz::Finding(std::string("a PLY that was read cannot be written back: ") +
                  e.what());
  }
  return 0;
}
