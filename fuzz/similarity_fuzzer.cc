// libFuzzer target: the similarity-transform text (`watergs attack
// --attack similarity:...`, `watergs extract --scene_transform`). A parsed
// transform must be finite, a proper rotation with a positive scale, and
// survive its own printed form.
#include <cmath>

#include "distortion/file_attacks.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string text(reinterpret_cast<const char*>(data), size);
  SimilarityTransform t;
  try {
    t = ParseSimilarity(text);
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e);
    return 0;
  }
  if (!t.rotation.allFinite() || !t.translation.allFinite() ||
      !std::isfinite(t.scale) || !(t.scale > 0)) {
    fuzz::Finding("parsed transform is not finite with a positive scale");
  }
  const Eigen::Matrix3d rtr = t.rotation.transpose() * t.rotation;
  if (!rtr.isIdentity(1e-9) || std::abs(t.rotation.determinant() - 1) > 1e-9) {
    fuzz::Finding("parsed rotation is not proper");
  }
  SimilarityTransform back;
  try {
    back = ParseSimilarity(ToString(t));
  } catch (const Error& e) {
    fuzz::Finding(std::string("printed transform does not parse: ") + e.what());
  }
  if (!back.rotation.isApprox(t.rotation, 1e-8) ||
      std::abs(back.scale - t.scale) > 1e-8 * t.scale) {
    fuzz::Finding("transform does not survive its printed form");
  }
  return 0;
}
