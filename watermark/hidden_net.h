// The HiDDeN encoder and decoder networks (Zhu et al. 2018) used by WATER-GS
// to train its universal watermark decoder.
//
// Conventions: images are NCHW in [-1, 1] (an ImageRGB value v maps to
// 2v - 1); messages enter the encoder as +-1 (bit 1 -> +1, bit 0 -> -1);
// decoder logits are positive for bit 1 (BCE targets 0/1). Both networks are
// fully convolutional up to a global average pool, so they accept any image
// size.
#pragma once

#include <memory>
#include <random>
#include <vector>

#include "watermark/nn_layers.h"

namespace watergs {

struct HiddenConfig {
  // Message length L in bits.
  int num_bits = 48;
  // Channels of the hidden convolutions.
  int channels = 64;
  // Conv-BN-ReLU blocks before the message is concatenated (encoder).
  int encoder_blocks = 4;
  // Conv-BN-ReLU blocks before the L-channel block (decoder).
  int decoder_blocks = 7;
};

// conv3x3 + BatchNorm + ReLU, keeping its activations for Backward.
class ConvBnRelu {
 public:
  ConvBnRelu(const std::string& name, int in, int out, std::mt19937* rng);
  // x [N,in,H,W] -> output() [N,out,H,W].
  void Forward(const Tensor& x, bool training);
  // dout (overwritten) -> dx (skipped when null).
  void Backward(const Tensor& x, Tensor* dout, Tensor* dx, bool weight_grads,
                bool training);
  const Tensor& output() const { return out_; }
  void CollectParameters(std::vector<Parameter*>* out);
  // The block's layers.
  Conv2d conv;
  BatchNorm2d bn;

 private:
  // Convolution output, block output (after ReLU), gradient at conv output.
  Tensor conv_out_, out_, dconv_;
};

// E(cover, message) = cover + conv1x1(CBR(concat(message planes, features,
// cover))), features = 4 x CBR(cover). The residual form (as in later HiDDeN
// re-implementations) lets the encoder start imperceptible.
class HiddenEncoder {
 public:
  HiddenEncoder(const HiddenConfig& config, std::mt19937* rng);
  // cover [N,3,H,W], message N*L values +-1 -> watermarked [N,3,H,W].
  const Tensor& Forward(const Tensor& cover, const std::vector<float>& message,
                        bool training);
  // dwatermarked [N,3,H,W]: adds weight gradients (cover gets none).
  void Backward(const Tensor& dwatermarked, bool training);
  void CollectParameters(std::vector<Parameter*>* out);
  // Multiply-adds per pixel of one forward pass.
  int64_t MacsPerPixel() const;

 private:
  HiddenConfig config_;
  // Feature blocks on the cover.
  std::vector<ConvBnRelu> blocks_;
  // Block on [message planes, features, cover].
  ConvBnRelu after_concat_;
  // 1x1 convolution to the 3-channel residual.
  Conv2d final_;
  // Input of the last Forward (owned by the caller).
  const Tensor* cover_ = nullptr;
  // Activations of the last Forward and gradient scratch.
  Tensor concat_, residual_, watermarked_, dconcat_, dblock_, dblock_in_;
};

// D(image) = Linear(GAP(CBR_L(7 x CBR(image)))): L logits per image.
class HiddenDecoder {
 public:
  HiddenDecoder(const HiddenConfig& config, std::mt19937* rng);
  // image [N,3,H,W] -> logits [N,L,1,1].
  const Tensor& Forward(const Tensor& image, bool training);
  // dlogits [N,L,1,1] -> dimage (skipped when null); weight gradients only
  // when weight_grads.
  void Backward(const Tensor& dlogits, Tensor* dimage, bool weight_grads,
                bool training);
  void CollectParameters(std::vector<Parameter*>* out);
  int64_t MacsPerPixel() const;
  int num_bits() const { return config_.num_bits; }

 private:
  HiddenConfig config_;
  // decoder_blocks feature blocks, then the L-channel block.
  std::vector<ConvBnRelu> blocks_;
  // Linear(L, L) after global average pooling.
  Linear linear_;
  // Input of the last Forward (owned by the caller).
  const Tensor* image_ = nullptr;
  // Activations of the last Forward and gradient scratch.
  Tensor pooled_, logits_, dpooled_, da_, db_;
};

}  // namespace watergs
