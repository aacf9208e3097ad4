// Attacks on rendered images before they are decoded: what happens to a
// watermark when the renders, not the model, are shared (JPEG compression,
// resizing, cropping). Used by `watergs extract --image_attack` and
// `watergs eval`. JPEG reuses the decoder-training noise layer's encoder.
#pragma once

#include <string>
#include <vector>

#include "gaussian/image.h"

namespace watergs {

enum class ImageAttackKind { kJpeg, kResize, kCrop };

// One image attack and its strength.
struct ImageAttackSpec {
  // Which attack.
  ImageAttackKind kind = ImageAttackKind::kJpeg;
  // JPEG: quality 1-100; resize: scale factor in (0, 4]; crop: fraction of
  // each side kept, in (0, 1].
  double value = 50;
};

// Parses "jpeg:Q", "resize:F" or "crop:F"; throws Error naming the text.
ImageAttackSpec ParseImageAttack(const std::string& text);
// Comma-separated list; throws Error if empty.
std::vector<ImageAttackSpec> ParseImageAttackList(const std::string& text);
// "jpeg:50" etc., read back by ParseImageAttack.
std::string ToString(const ImageAttackSpec& spec);

// Applies the attack to an RGB image in [0, 1] (values are clamped first):
//   jpeg:Q    8-bit quantisation, OpenCV JPEG encode at quality Q, decode;
//   resize:F  resized to round(F W) x round(F H) (at least 1 x 1), INTER_AREA
//             when shrinking, bilinear when enlarging;
//   crop:F    the centred window of round(F W) x round(F H) pixels.
ImageRGB ApplyImageAttack(const ImageAttackSpec& spec, const ImageRGB& image);

// `image` resized to width x height (INTER_AREA when shrinking, bilinear when
// enlarging, clamped to [0, 1]); the image itself when it has that size.
ImageRGB ResizeTo(const ImageRGB& image, int width, int height);

// What the owner decodes after `spec` hit `render`: the attacked image
// brought back to the render's scale. The watermark lives at the scale it was
// embedded at, so a resized copy is resized back to the render's size before
// decoding (resize:0.5 on the demo: 0.95% of bits wrong a view instead of
// 35.5%); a crop keeps its pixels and JPEG its size.
ImageRGB AttackAsDecoded(const ImageAttackSpec& spec, const ImageRGB& render);

}  // namespace watergs
