// Which renderer's conventions the owner's reference follows: a screenshot
// of a web viewer differs from watergs' render of the same file by far more
// than the watermark (gaussian-splats-3d: 25.9 dB on the demo, the
// watermark 37 dB from the raw renders), and the owner's reading subtracts
// the raw model's render from the screenshot. `detect` renders that
// reference under each candidate set of conventions
// (gaussian/render_conventions.h) and keeps, per image, the one whose
// render matches the image best.
#pragma once

#include <string>
#include <vector>

#include "gaussian/image.h"
#include "gaussian/render_conventions.h"

namespace watergs {

// The candidates `--reference_conventions` names: "auto" is every set of the
// registry, watergs' first; one name is that set alone. Fails in one line on
// an unknown name.
std::vector<NamedRenderConventions> ReferenceCandidates(
    const std::string& option_value);

// The candidate whose reference matches the image best.
struct ReferenceChoice {
  size_t best = 0;           // index into the candidates
  std::vector<double> psnr;  // dB, per candidate
};

// PSNR of each of `references` (one per candidate, the image's size)
// against `image`; the highest wins, the earlier one on a tie (so watergs'
// own conventions win whenever another set renders the same image).
ReferenceChoice ChooseReference(const ImageRGB& image,
                                const std::vector<ImageRGB>& references);

}  // namespace watergs
