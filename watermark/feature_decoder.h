// The steerable random-feature decoder: WATER-GS's default universal decoder.
//
// WATER-GS keeps only the decoder of a watermarking network and steers the
// 3DGS scene into it, so the decoder needs no encoder; it must be steerable
// (a small image change sets any message), robust, and balanced (fair,
// nearly uncorrelated bits on unmarked images, so the p-value holds). A
// shallow, wide network of random features, whitened on natural photos, is
// all three without training (docs/decoder_design.md):
//
//   D(x) = A . GAP(ReLU(conv_k(avgpool_p(2x - 1)))) + b
//
// (optionally conv_k reads avgpool_p(.) minus its box mean: `highpass`)
//
// with the convolution's outputs standardised on photos (BatchNorm folded
// in) and A = s P Sigma^-1/2, b = -A mu: mu, Sigma the mean and covariance of
// the pooled features over photo crops, P a random orthogonal L x C
// projection, s the logit scale. On the calibration crops the L logits are
// then zero-mean, uncorrelated and of standard deviation s.
//
// Weights file: the network container (network_file.h), kind
// "feature-decoder", meta num_bits, channels, pool, kernel, input_range (1:
// images mapped to [-1, 1]), design (1), highpass (only when > 0); tensors
// conv.weight [C,3,k,k], conv.bias [C], linear.weight [L,C], linear.bias [L].
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "watermark/bit_decoder.h"
#include "watermark/network_file.h"
#include "watermark/nn_layers.h"

namespace watergs {

inline constexpr char kFeatureDecoderKind[] = "feature-decoder";

struct FeatureDecoderConfig {
  // Message length L.
  int num_bits = 48;
  // Width C of the random feature layer.
  int channels = 2048;
  // Side of the average pooling applied to the image first (1: none).
  int pool = 4;
  // Side of the convolution's kernel (odd).
  int kernel = 3;
  // 0: the features read the pooled image. r > 0: they read its residual,
  // the pooled image minus its (2r+1)^2 box mean, so the scene's smooth
  // shading and colour (what an unmarked view's logits lean on) is not read.
  int highpass = 0;
};

// The network: avgpool -> conv -> ReLU -> global average pool -> linear.
class FeatureNet {
 public:
  // Random convolution (PyTorch's default initialisation) and a zero linear
  // layer; calibration (feature_decoder_calibration.h) sets the rest.
  FeatureNet(const FeatureDecoderConfig& config, uint32_t seed);

  // image [N,3,H,W] in [-1,1], H and W >= pool -> logits [N,L,1,1]. Keeps
  // what Backward needs. One image goes through the convolution in strips of
  // rows (StripRows), keeping only the ReLU's mask (one bit a value): the
  // whole C x h x w output of a 798x531 frame would be 868 MB.
  const Tensor& Forward(const Tensor& image);
  // Pooled features [N,C,1,1] of the last Forward (before the linear layer).
  const Tensor& features() const { return features_; }
  // image [N,3,H,W] -> the convolution's output [N,C,h,w] before the ReLU
  // (calibration's statistics); a later Backward is not allowed.
  void ConvolutionOutput(const Tensor& image, Tensor* y);
  // Largest convolution output one strip may hold (bytes): a single image
  // whose output is larger goes through in several strips, whose results
  // equal one strip's to float rounding. Tests set it small.
  void set_max_strip_bytes(size_t bytes) { max_strip_bytes_ = bytes; }
  // Strips the last single-image Forward took (1: the whole image at once).
  int last_num_strips() const { return last_num_strips_; }
  // dlogits [N,L,1,1] -> dimage [N,3,H,W] of the last Forward's image.
  void Backward(const Tensor& dlogits, Tensor* dimage);
  // dfeatures [1,C,1,1] -> dimage [1,3,H,W]: Backward from the pooled
  // features (before the linear layer) of the last single-image Forward.
  void FeatureBackward(const Tensor& dfeatures, Tensor* dimage);

  const FeatureDecoderConfig& config() const { return config_; }
  // Multiply-adds of one forward pass per input pixel.
  double MacsPerPixel() const;

  Conv2d conv;
  Linear linear;

 private:
  FeatureDecoderConfig config_;
  // Input of the last Forward (owned by the caller).
  const Tensor* image_ = nullptr;
  // Activations of the last Forward and gradient scratch.
  Tensor pooled_, residual_, conv_out_, features_, logits_, dfeatures_, drelu_,
      dresidual_, dpooled_;

  size_t max_strip_bytes_ = size_t(128) << 20;
  int last_num_strips_ = 0;
  // Batch size of the last Forward.
  int last_n_ = 0;
  // The ReLU's mask (conv output > 0) of the last single-image Forward, one
  // bit per value, channel-major, in 64-bit words per channel.
  std::vector<uint64_t> relu_mask_;
  size_t mask_words_per_channel_ = 0;
  // Strip scratch, kept between calls (at most max_strip_bytes_ of output):
  // the convolution's input and output rows of one strip.
  Tensor strip_in_, strip_out_;

  // The convolution's input of the last Forward: the (pooled) image or its
  // residual.
  const Tensor& ConvInput() const;
  // Pooling and high-pass of `image` (checked): what ConvInput returns.
  void PrepareConvInput(const Tensor& image);
  // Output rows per strip for a conv input of width w and height h.
  int StripRows(int h, int w) const;
  // Single-image ReLU + global average pool of the convolution, by strips:
  // features_ and relu_mask_.
  void StripForward(const Tensor& input);
  // dfeatures [1,C,1,1] -> dconv_input [1,3,h,w] through relu_mask_.
  void StripBackward(const Tensor& dfeatures, Tensor* dconv_input);
  // dconv_input -> dimage through the residual and the pooling.
  void InputBackward(Tensor* dconv_input, Tensor* dimage);
  std::vector<float> dcol_;
};

// image [N,C,H,W] -> [N,C,H/p,W/p]: the mean of each p x p block (rows and
// columns beyond a multiple of p are dropped).
void AvgPoolForward(const Tensor& x, int p, Tensor* y);
// dy [N,C,H/p,W/p] -> dx [N,C,H,W] (H, W from `like`): each block's pixels
// get dy / p^2, the dropped border 0.
void AvgPoolBackward(const Tensor& dy, int p, const Tensor& like, Tensor* dx);

// x [N,C,H,W] -> y = x - B x, B the mean over the (2r+1)^2 box around each
// pixel clipped to the image (each pixel divided by its own box's count).
void HighpassForward(const Tensor& x, int r, Tensor* y);
// dy -> dx = dy - B^T dy (the exact adjoint of HighpassForward).
void HighpassBackward(const Tensor& dy, int r, Tensor* dx);

// The network as a weights file, and back; `path` names the file in errors.
// Refuses another kind, missing/extra/misshapen tensors, non-finite weights,
// unsupported architecture values and num_bits != expected_bits (if > 0).
NetworkFile FeatureNetToFile(FeatureNet& net);
std::unique_ptr<FeatureNet> FeatureNetFromFile(const std::string& path,
                                               const NetworkFile& file,
                                               int expected_bits = 0);

// The CPU BitDecoder of a FeatureNet.
class FeatureDecoder : public CachedTensorDecoder {
 public:
  // Loads a weights file with FeatureNetFromFile's checks.
  static std::unique_ptr<FeatureDecoder> Load(const std::string& path,
                                              int expected_bits = 0);
  explicit FeatureDecoder(std::unique_ptr<FeatureNet> net);

  int NumBits() const override;
  FeatureNet& net() { return *net_; }

 protected:
  const Tensor& ForwardTensor(const Tensor& input) override;
  void BackwardTensor(const Tensor& dlogits, Tensor* dinput) override;

 private:
  std::unique_ptr<FeatureNet> net_;
};

}  // namespace watergs
