// Frozen universal decoder (see decoder.h).
#include "watermark/decoder.h"

#include <cstring>

#include "gaussian/error.h"
#include "watermark/network_image.h"

namespace watergs {

Decoder Decoder::Load(const std::string& path, int expected_bits) {
  std::unique_ptr<HiddenModel> model =
      LoadHiddenModel(path, false, expected_bits);
  Decoder decoder(model.get());
  decoder.owned_ = std::move(model);
  return decoder;
}

Decoder::Decoder(HiddenModel* model) : model_(model) {}
Decoder::Decoder(Decoder&&) noexcept = default;
Decoder& Decoder::operator=(Decoder&&) noexcept = default;
Decoder::~Decoder() = default;

int Decoder::NumBits() const { return model_->config.num_bits; }

void Decoder::ForwardIfNeeded(const ImageRGB& image) {
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
  const Tensor& logits = model_->decoder->Forward(input_, false);
  logits_.assign(logits.data.begin(), logits.data.end());
  has_forward_ = true;
}

std::vector<float> Decoder::Logits(const ImageRGB& image) {
  ForwardIfNeeded(image);
  return logits_;
}

void Decoder::InputGradient(const ImageRGB& image,
                            const std::vector<float>& dlogits,
                            ImageRGB* dimage) {
  if (int(dlogits.size()) != NumBits())
    Fail("decoder: " + std::to_string(dlogits.size()) +
         " logit gradients for a " + std::to_string(NumBits()) +
         "-bit decoder");
  ForwardIfNeeded(image);
  dlogits_.Resize(1, NumBits(), 1, 1);
  std::copy(dlogits.begin(), dlogits.end(), dlogits_.data.begin());
  model_->decoder->Backward(dlogits_, &dinput_, false, false);
  if (dimage->width != image.width || dimage->height != image.height ||
      dimage->data.size() != image.data.size())
    *dimage = ImageRGB(image.width, image.height);
  const size_t hw = dinput_.PlaneSize();
  // d/d(image) = 2 d/d(input) since input = 2 image - 1.
  for (size_t p = 0; p < hw; ++p)
    for (int c = 0; c < 3; ++c)
      dimage->data[p * 3 + c] = 2.f * dinput_.data[c * hw + p];
}

ImageRGB Decoder::InputGradient(const ImageRGB& image,
                                const std::vector<float>& dlogits) {
  ImageRGB dimage;
  InputGradient(image, dlogits, &dimage);
  return dimage;
}

}  // namespace watergs
