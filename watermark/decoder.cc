// Frozen universal decoder (see decoder.h).
#include "watermark/decoder.h"

#include "gaussian/util/error.h"

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

const Tensor& Decoder::ForwardTensor(const Tensor& input) {
  return model_->decoder->Forward(input, false);
}

void Decoder::BackwardTensor(const Tensor& dlogits, Tensor* dinput) {
  model_->decoder->Backward(dlogits, dinput, false, false);
}

ImageRGB Decoder::InputGradient(const ImageRGB& image,
                                const std::vector<float>& dlogits) {
  ImageRGB dimage;
  InputGradient(image, dlogits, &dimage);
  return dimage;
}

}  // namespace watergs
