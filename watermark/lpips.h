// LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features
// as a Perceptual Metric"), VGG variant v0.1, on the project's NN layers.
// Weights come from datasets_scripts/download_lpips_weights.sh, converted by
// convert_lpips_weights.py into "watergs LPIPS-VGG weights v1" (format in
// that script): the ImageNet VGG-16 conv trunk and the five linear heads.
//
// Forward pass, as the reference implementation: x in [0, 1] -> 2x - 1 ->
// (x - shift) / scale per channel; VGG-16 convs (3x3, padding 1, ReLU) with
// 2x2 stride-2 max-pooling (floor) after convs 2, 4, 7 and 10; taps relu1_2,
// relu2_2, relu3_3, relu4_3, relu5_3, each divided by its per-pixel channel
// L2 norm (+1e-10); LPIPS = sum over taps of the spatial mean of
// sum_c w_c (f0 - f1)^2. Images need both sides >= 16 (four pools).
// Memory: the first convs' im2col buffers take about 2.5 KB per pixel.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "watermark/nn_layers.h"
#include "watermark/tensor.h"

namespace watergs {

// x [N,C,H,W] -> y [N,C,H/2,W/2]: max over 2x2 blocks, stride 2 (an odd last
// row/column is dropped, as PyTorch's MaxPool2d(2, 2)).
void MaxPool2x2Forward(const Tensor& x, Tensor* y);

class Lpips {
 public:
  // Reads a weights file; throws Error naming the file when it is missing,
  // truncated, fails its CRC, or lacks a tensor or has a wrong shape.
  static std::unique_ptr<Lpips> Load(const std::string& path);
  // The same network with random weights (for benchmarks: cost does not
  // depend on the weights).
  static std::unique_ptr<Lpips> WithRandomWeights(uint32_t seed);

  // The five unit-normalised VGG taps of one image.
  struct Features {
    std::array<Tensor, 5> taps;
  };
  // Features of an RGB image in [0, 1] (clamped); throws Error if a side is
  // below 16 pixels.
  Features Extract(const ImageRGB& image);
  // LPIPS between two images' features (same image size).
  double Distance(const Features& a, const Features& b) const;
  // LPIPS between two images of equal size.
  double Distance(const ImageRGB& a, const ImageRGB& b);

 private:
  Lpips() = default;

  // Input normalisation.
  std::array<float, 3> shift_{}, scale_{};
  // The 13 VGG-16 convolutions in order.
  std::vector<std::unique_ptr<Conv2d>> convs_;
  // Linear head weights per tap (64, 128, 256, 512, 512 values).
  std::array<std::vector<float>, 5> heads_;
};

}  // namespace watergs
