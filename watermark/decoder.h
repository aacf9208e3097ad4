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

// The CPU implementation of BitDecoder.
class Decoder : public BitDecoder {
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
  // image (any size >= 1x1) -> L logits.
  std::vector<float> Logits(const ImageRGB& image) override;
  // image, dLoss/dLogits (L values) -> dLoss/dImage (same size as image).
  // Re-runs the forward pass only when `image` differs from the last one.
  void InputGradient(const ImageRGB& image, const std::vector<float>& dlogits,
                     ImageRGB* dimage) override;
  ImageRGB InputGradient(const ImageRGB& image,
                         const std::vector<float>& dlogits);

 private:
  // Runs the forward pass unless `image` is the cached input.
  void ForwardIfNeeded(const ImageRGB& image);

  // The model when loaded from a file (null when wrapped).
  std::unique_ptr<HiddenModel> owned_;
  // The model in use.
  HiddenModel* model_ = nullptr;
  // Network input (NCHW, [-1,1]) of the last forward pass, and gradients.
  Tensor input_, dlogits_, dinput_;
  // The image of the last forward pass (HWC) and its logits.
  std::vector<float> cached_pixels_, logits_;
  // True once a forward pass has run.
  bool has_forward_ = false;
};

}  // namespace watergs
