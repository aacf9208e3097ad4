// The universal watermark decoder D used frozen by WATER-GS embedding and
// extraction: loads a trained HiDDeN decoder, reads L logits from an image,
// and gives dLoss/dImage for a given dLoss/dLogits (BatchNorm in inference
// mode, no weight gradients). Images are ImageRGB (HWC floats in [0, 1]);
// they are mapped to the network's [-1, 1] input internally. Logit i > 0
// reads bit i as 1. Activations live in buffers reused between calls of the
// same image size, so a fine-tuning loop allocates nothing per call beyond
// Eigen's matrix-product blocking.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "watermark/bit_decoder.h"
#include "watermark/hidden_model.h"

namespace watergs {

// The CPU implementation of BitDecoder for HiDDeN decoders.
class Decoder : public CachedTensorDecoder {
 public:
  // Loads the decoder of a weights file (see hidden_model.h); throws Error
  // naming the file when it is missing, truncated, corrupted, not a HiDDeN
  // model, or reads a number of bits other than expected_bits (if > 0).
  static Decoder Load(const std::string& path, int expected_bits = 0);
  // Wraps an in-memory model (it must outlive the Decoder).
  explicit Decoder(HiddenModel* model);
  Decoder(Decoder&&) noexcept;
  Decoder& operator=(Decoder&&) noexcept;
  ~Decoder() override;

  // Message length L.
  int NumBits() const override;
  using CachedTensorDecoder::InputGradient;
  // image, dLoss/dLogits (L values) -> dLoss/dImage (same size as image).
  ImageRGB InputGradient(const ImageRGB& image,
                         const std::vector<float>& dlogits);

 protected:
  const Tensor& ForwardTensor(const Tensor& input) override;
  void BackwardTensor(const Tensor& dlogits, Tensor* dinput) override;

 private:
  // The model when loaded from a file (null when wrapped).
  std::unique_ptr<HiddenModel> owned_;
  // The model in use.
  HiddenModel* model_ = nullptr;
};

}  // namespace watergs
