// Texture masking for the embedding's image term: where an image is
// textured, a change is harder to see (the contrast masking of JND models),
// so a squared error there may weigh less.
#pragma once

#include <vector>

#include "gaussian/image.h"

namespace watergs {

// H x W weights, mean 1: 1 / (1 + sigma / sigma0) per pixel, sigma the
// standard deviation of the image's luminance (Rec. 601) over the 7 x 7
// pixels around it (borders reflected), then scaled to a mean of 1.
std::vector<float> TextureMaskingWeights(const ImageRGB& image, double sigma0);

}  // namespace watergs
