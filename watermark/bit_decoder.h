// What WATER-GS embedding, extraction and evaluation need from the frozen
// watermark decoder D: its message length, the logits it reads from an
// image and dLoss/dImage for a dLoss/dLogits. Implemented on the CPU by
// Decoder (decoder.h) and on the GPU by CudaDecoder (cuda/cuda_hidden.h);
// LoadBitDecoder picks one for `--device`.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/image.h"
#include "watermark/tensor.h"

namespace watergs {

class BitDecoder {
 public:
  virtual ~BitDecoder() = default;

  // Message length L.
  virtual int NumBits() const = 0;
  // image (HWC in [0, 1], any size >= 1x1) -> L logits; logit i > 0 reads
  // bit i as 1.
  virtual std::vector<float> Logits(const ImageRGB& image) = 0;
  // image, dLoss/dLogits (L values) -> dLoss/dImage (same size as image).
  virtual void InputGradient(const ImageRGB& image,
                             const std::vector<float>& dlogits,
                             ImageRGB* dimage) = 0;

 protected:
  // Fails (one line) unless `count` is NumBits(): InputGradient's check.
  void CheckLogitGradients(size_t count) const;

  BitDecoder() = default;
  BitDecoder(const BitDecoder&) = default;
  BitDecoder(BitDecoder&&) = default;
  BitDecoder& operator=(const BitDecoder&) = default;
  BitDecoder& operator=(BitDecoder&&) = default;
};

// A CPU BitDecoder over a network on NCHW tensors: maps images to the
// network's [-1, 1] input, keeps the last forward pass (a fine-tuning loop
// asks for the logits and the gradient of the same render; a memcmp decides)
// and maps the input gradient back to HWC. Subclasses supply the network.
class CachedTensorDecoder : public BitDecoder {
 public:
  std::vector<float> Logits(const ImageRGB& image) override;
  void InputGradient(const ImageRGB& image, const std::vector<float>& dlogits,
                     ImageRGB* dimage) override;

 protected:
  // input [1,3,H,W] in [-1, 1] -> logits [1,L,1,1].
  virtual const Tensor& ForwardTensor(const Tensor& input) = 0;
  // dlogits [1,L,1,1] -> dinput [1,3,H,W] of the last ForwardTensor.
  virtual void BackwardTensor(const Tensor& dlogits, Tensor* dinput) = 0;

 private:
  // Runs the forward pass unless `image` is the cached input.
  void ForwardIfNeeded(const ImageRGB& image);

  // Network input of the last forward pass, and gradient buffers.
  Tensor input_, dlogits_, dinput_;
  // The image of the last forward pass (HWC) and its logits.
  std::vector<float> cached_pixels_, logits_;
  bool has_forward_ = false;
};

// The decoder watergs ships (watermark/models/decoder_48.bin of the source
// tree this binary was built from): every command's default --decoder.
std::string ShippedDecoderPath();
// --decoder's help text, the same in every command.
inline constexpr char kDecoderHelp[] =
    "Decoder weights file (default: the shipped 48-bit decoder, which "
    "reads what watergs embeds with it)";

// Loads the decoder of a weights file onto `device` with Decoder::Load's
// checks and errors (expected_bits > 0 also checks L). Throws Error naming
// the file for Device::kCuda when this build or machine has no usable GPU.
std::unique_ptr<BitDecoder> LoadBitDecoder(const std::string& path,
                                           Device device,
                                           int expected_bits = 0);

}  // namespace watergs
