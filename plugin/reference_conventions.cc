// The owner's reference's candidate conventions and the choice among them.
#include "plugin/reference_conventions.h"

#include "gaussian/loss.h"
#include "gaussian/util/error.h"

namespace watergs {

std::vector<NamedRenderConventions> ReferenceCandidates(
    const std::string& option_value) {
  if (option_value == "auto") return RenderConventionsRegistry();
  return {FindRenderConventions(option_value, "--reference_conventions")};
}

ReferenceChoice ChooseReference(const ImageRGB& image,
                                const std::vector<ImageRGB>& references) {
  if (references.empty()) Fail("detect: no reference to choose from");
  ReferenceChoice choice;
  for (size_t k = 0; k < references.size(); ++k) {
    choice.psnr.push_back(Psnr(references[k], image));
    if (choice.psnr[k] > choice.psnr[choice.best]) choice.best = k;
  }
  return choice;
}

}  // namespace watergs
