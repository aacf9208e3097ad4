// 2D noise layers between the HiDDeN encoder and decoder during training:
// identity, crop, dropout, resize, Gaussian blur and JPEG. Each maps a
// watermarked batch [N,3,H,W] in [-1,1] (and its cover) to the noised batch
// the decoder sees, and passes gradients back to the watermarked batch.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "watermark/tensor.h"

namespace watergs {

enum class NoiseKind { kIdentity, kCrop, kDropout, kResize, kBlur, kJpeg };

// Strengths (fixed so validation figures are comparable between runs).
struct NoiseStrengths {
  // Crop: a random window of this fraction of each side (0.7: ~50% area).
  float crop_side = 0.7f;
  // Dropout: fraction of pixels taken from the cover instead (HiDDeN).
  float dropout = 0.3f;
  // Resize: scale drawn uniformly in [resize_min, 1], bilinear.
  float resize_min = 0.5f;
  // Blur: Gaussian sigma in pixels (kernel radius ceil(2 sigma)).
  float blur_sigma = 1.0f;
  // JPEG quality (OpenCV encoder); gradient passed straight through.
  int jpeg_quality = 50;
};

// "identity", "crop", ...
const char* NoiseName(NoiseKind kind);
// Comma-separated names -> kinds; throws Error naming an unknown entry.
std::vector<NoiseKind> ParseNoiseList(const std::string& list);

class ImageNoise {
 public:
  explicit ImageNoise(NoiseStrengths strengths = {}) : strengths_(strengths) {}
  // watermarked, cover [N,3,H,W] -> noised (crop and resize shrink H, W).
  void Forward(NoiseKind kind, const Tensor& watermarked, const Tensor& cover,
               Tensor* noised, std::mt19937* rng);
  // Gradient of the last Forward: dnoised -> dwatermarked [N,3,H,W].
  void Backward(const Tensor& dnoised, Tensor* dwatermarked) const;

 private:
  NoiseStrengths strengths_;
  // Layer applied by the last Forward.
  NoiseKind kind_ = NoiseKind::kIdentity;
  // Input shape of the last Forward.
  int n_ = 0, h_ = 0, w_ = 0;
  // Crop window origin.
  int crop_x_ = 0, crop_y_ = 0;
  // Dropout: 1 where the watermarked pixel was kept (per pixel, all channels).
  std::vector<unsigned char> keep_;
  // Blur kernel (normalised), radius = size / 2.
  std::vector<float> kernel_;
};

}  // namespace watergs
