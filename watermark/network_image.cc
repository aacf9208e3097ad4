// The networks' image convention (see network_image.h).
#include "watermark/network_image.h"

#include <algorithm>

namespace watergs {

void ImageToTensor(const ImageRGB& image, bool clamp, Tensor* tensor) {
  tensor->Resize(1, 3, image.height, image.width);
  const size_t hw = tensor->PlaneSize();
  for (size_t p = 0; p < hw; ++p) {
    for (int c = 0; c < 3; ++c) {
      const float v = image.data[p * 3 + c];
      tensor->data[c * hw + p] =
          2.f * (clamp ? std::clamp(v, 0.f, 1.f) : v) - 1.f;
    }
  }
}

ImageRGB TensorToImage(const Tensor& tensor) {
  ImageRGB image(tensor.w, tensor.h);
  const size_t hw = tensor.PlaneSize();
  for (size_t p = 0; p < hw; ++p) {
    for (int c = 0; c < 3; ++c) {
      image.data[p * 3 + c] =
          std::clamp(0.5f * (tensor.data[c * hw + p] + 1.f), 0.f, 1.f);
    }
  }
  return image;
}

}  // namespace watergs
