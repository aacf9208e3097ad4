// The HiDDeN networks' image convention, in one place: an ImageRGB (HWC,
// values in [0, 1]) is the network tensor [1,3,H,W] of 2 v - 1, and a
// network's output image maps back by (t + 1) / 2.
#pragma once

#include "gaussian/image.h"
#include "watermark/tensor.h"

namespace watergs {

// image -> tensor [1,3,H,W] = 2 v - 1 (v clamped to [0, 1] first when
// `clamp`; the decoder reads renders as they are).
void ImageToTensor(const ImageRGB& image, bool clamp, Tensor* tensor);
// tensor [1,3,H,W] -> image of (t + 1) / 2, clamped to [0, 1].
ImageRGB TensorToImage(const Tensor& tensor);

}  // namespace watergs
