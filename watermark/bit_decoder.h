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
  BitDecoder() = default;
  BitDecoder(const BitDecoder&) = default;
  BitDecoder(BitDecoder&&) = default;
  BitDecoder& operator=(const BitDecoder&) = default;
  BitDecoder& operator=(BitDecoder&&) = default;
};

// Loads the decoder of a weights file onto `device` with Decoder::Load's
// checks and errors (expected_bits > 0 also checks L). Throws Error naming
// the file for Device::kCuda when this build or machine has no usable GPU.
std::unique_ptr<BitDecoder> LoadBitDecoder(const std::string& path,
                                           Device device,
                                           int expected_bits = 0);

}  // namespace watergs
