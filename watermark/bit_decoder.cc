// LoadBitDecoder: by the weights file's kind, the random-feature decoder or
// the HiDDeN decoder, on the CPU, or on the GPU backend's twins
// (watermark/backend.h) read from the same file.
#include "watermark/bit_decoder.h"

#include <cstring>

#include "gaussian/util/error.h"
#include "watermark/backend.h"
#include "watermark/decoder.h"
#include "watermark/feature_decoder.h"
#include "watermark/network_file.h"
#include "watermark/network_image.h"

namespace watergs {

void BitDecoder::CheckLogitGradients(size_t count) const {
  if (int(count) != NumBits())
    Fail("decoder: " + std::to_string(count) + " logit gradients for a " +
         std::to_string(NumBits()) + "-bit decoder");
}

void CachedTensorDecoder::ForwardIfNeeded(const ImageRGB& image) {
  const size_t count = image.data.size();
  if (image.width <= 0 || image.height <= 0 ||
      count != size_t(image.width) * image.height * 3)
    Fail("decoder: image of " + std::to_string(image.width) + "x" +
         std::to_string(image.height) + " with " + std::to_string(count) +
         " values");
  if (has_forward_ && input_.w == image.width && input_.h == image.height &&
      std::memcmp(cached_pixels_.data(), image.data.data(),
                  count * sizeof(float)) == 0)
    return;
  cached_pixels_.assign(image.data.begin(), image.data.end());
  ImageToTensor(image, false, &input_);
  const Tensor& logits = ForwardTensor(input_);
  logits_.assign(logits.data.begin(), logits.data.end());
  has_forward_ = true;
}

std::vector<float> CachedTensorDecoder::Logits(const ImageRGB& image) {
  ForwardIfNeeded(image);
  return logits_;
}

void CachedTensorDecoder::InputGradient(const ImageRGB& image,
                                        const std::vector<float>& dlogits,
                                        ImageRGB* dimage) {
  CheckLogitGradients(dlogits.size());
  ForwardIfNeeded(image);
  dlogits_.Resize(1, NumBits(), 1, 1);
  std::copy(dlogits.begin(), dlogits.end(), dlogits_.data.begin());
  BackwardTensor(dlogits_, &dinput_);
  if (dimage->width != image.width || dimage->height != image.height ||
      dimage->data.size() != image.data.size())
    *dimage = ImageRGB(image.width, image.height);
  const size_t hw = dinput_.PlaneSize();
  // d/d(image) = 2 d/d(input) since input = 2 image - 1.
  for (size_t p = 0; p < hw; ++p)
    for (int c = 0; c < 3; ++c)
      dimage->data[p * 3 + c] = 2.f * dinput_.data[c * hw + p];
}

std::string ShippedDecoderPath() { return WATERGS_SHIPPED_DECODER; }

std::unique_ptr<BitDecoder> LoadBitDecoder(const std::string& path,
                                           Device device, int expected_bits) {
  const NetworkFile file = ReadNetworkFile(path);
  const bool feature = file.kind == kFeatureDecoderKind;
  if (device == Device::kCpu) {
    if (feature) {
      return std::make_unique<FeatureDecoder>(
          FeatureNetFromFile(path, file, expected_bits));
    }
    return std::make_unique<Decoder>(Decoder::Load(path, expected_bits));
  }
  std::string why;
  if (!CudaAvailable(&why)) {
    FailAt(path, "cannot load the decoder on the GPU: " + why);
  }
  return LoadGpuBitDecoder(path, expected_bits, feature);
}

}  // namespace watergs
