// The HiDDeN encoder and decoder (hidden_net.h) on the GPU, built from the
// weights of CPU networks (same parameter order as CollectParameters), and
// CudaDecoder: the frozen universal decoder of decoder.h (Logits,
// InputGradient) on the GPU, loaded from the same weights file (training:
// cuda_decoder_training.h). Parity with the CPU:
// tests/watermark/cuda_decoder_test.cc.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "gaussian/rasterizer.h"
#include "watermark/bit_decoder.h"
#include "watermark/cuda/cuda_nn.h"
#include "watermark/cuda/device_patch_decoder.h"
#include "watermark/hidden_model.h"

namespace watergs {

// conv3x3 + BatchNorm + ReLU keeping its activations (ConvBnRelu's twin).
class CudaConvBnRelu {
 public:
  // params: conv.weight, conv.bias, bn.gamma, bn.beta, bn.running_mean,
  // bn.running_var (ConvBnRelu::CollectParameters order). Momentum and
  // eps are BatchNorm2d's defaults, which the CPU blocks keep.
  CudaConvBnRelu(CudaNnContext* context, const std::vector<Parameter*>& params);
  // x [N,in,H,W] -> output() [N,out,H,W].
  void Forward(const DeviceTensor& x, bool training);
  // dout (overwritten) -> dx (skipped when null).
  void Backward(const DeviceTensor& x, DeviceTensor* dout, DeviceTensor* dx,
                bool weight_grads, bool training);
  const DeviceTensor& output() const { return out_; }
  void CollectParameters(std::vector<CudaParameter*>* out);
  // The block's layers.
  CudaConv2d conv;
  CudaBatchNorm2d bn;

 private:
  // Convolution output, block output (after ReLU), gradient at conv output.
  DeviceTensor conv_out_, out_, dconv_;
};

// HiddenDecoder's twin: D(image) = Linear(GAP(CBR_L(blocks x CBR(image)))).
class CudaHiddenDecoder {
 public:
  // Copies the weights of `cpu` (which may then go away).
  CudaHiddenDecoder(CudaNnContext* context, const HiddenConfig& config,
                    HiddenDecoder& cpu);
  // image [N,3,H,W] -> logits [N,L,1,1].
  const DeviceTensor& Forward(const DeviceTensor& image, bool training);
  // dlogits [N,L,1,1] -> dimage (skipped when null); weight gradients only
  // when weight_grads. Uses the activations of the last Forward.
  void Backward(const DeviceTensor& dlogits, DeviceTensor* dimage,
                bool weight_grads, bool training);
  void CollectParameters(std::vector<CudaParameter*>* out);
  int num_bits() const { return config_.num_bits; }

 private:
  HiddenConfig config_;
  // decoder_blocks feature blocks, then the L-channel block.
  std::vector<std::unique_ptr<CudaConvBnRelu>> blocks_;
  // Linear(L, L) after global average pooling.
  std::unique_ptr<CudaLinear> linear_;
  // Input of the last Forward (owned by the caller).
  const DeviceTensor* image_ = nullptr;
  // Activations of the last Forward and gradient scratch.
  DeviceTensor pooled_, logits_, dpooled_, da_, db_;
};

// HiddenEncoder's twin: cover + conv1x1(CBR([message planes, features,
// cover])), features = blocks x CBR(cover).
class CudaHiddenEncoder {
 public:
  CudaHiddenEncoder(CudaNnContext* context, const HiddenConfig& config,
                    HiddenEncoder& cpu);
  // cover [N,3,H,W], message N*L values +-1 (device) -> watermarked.
  const DeviceTensor& Forward(const DeviceTensor& cover,
                              const DeviceBuffer<float>& message,
                              bool training);
  // dwatermarked [N,3,H,W]: adds weight gradients (cover gets none).
  void Backward(const DeviceTensor& dwatermarked, bool training);
  void CollectParameters(std::vector<CudaParameter*>* out);

 private:
  HiddenConfig config_;
  // Feature blocks on the cover.
  std::vector<std::unique_ptr<CudaConvBnRelu>> blocks_;
  // Block on [message planes, features, cover].
  std::unique_ptr<CudaConvBnRelu> after_concat_;
  // 1x1 convolution to the 3-channel residual.
  std::unique_ptr<CudaConv2d> final_;
  // Input of the last Forward (owned by the caller).
  const DeviceTensor* cover_ = nullptr;
  // Activations of the last Forward and gradient scratch.
  DeviceTensor concat_, residual_, watermarked_, dconcat_, dblock_, dblock_in_;
};

// A HiddenModel on the device: both networks (encoder only if the CPU model
// has one), parameters in HiddenModel::AllParameters order.
struct CudaHiddenModel {
  CudaHiddenModel(CudaNnContext* context, HiddenModel& cpu);
  std::vector<CudaParameter*> AllParameters();
  // Device values (and gradients) back into `cpu` (the same architecture).
  void CopyToHost(HiddenModel* cpu);

  // Null when the CPU model has no encoder.
  std::unique_ptr<CudaHiddenEncoder> encoder;
  // Always present.
  std::unique_ptr<CudaHiddenDecoder> decoder;
};

// The frozen HiDDeN decoder (Decoder's twin) on the GPU: a BitDecoder the
// device-resident embedding step reads in place (DevicePatchDecoder).
class CudaDecoder : public DevicePatchDecoder {
 public:
  // Loads the decoder of a weights file as Decoder::Load does (same
  // checks, same errors). allow_tf32: see CudaNnContext (faster, ~1e-3
  // relative error; the parity tests use false).
  static CudaDecoder Load(const std::string& path, int expected_bits = 0,
                          bool allow_tf32 = false);
  // Copies the decoder weights of `model` (which may then go away).
  explicit CudaDecoder(HiddenModel& model, bool allow_tf32 = false);
  CudaDecoder(CudaDecoder&&) noexcept;
  CudaDecoder& operator=(CudaDecoder&&) noexcept;
  ~CudaDecoder() override;

  // Message length L.
  int NumBits() const override;
  // Logits and InputGradient of any image >= 1x1: DevicePatchDecoder's.
  using DevicePatchDecoder::InputGradient;
  ImageRGB InputGradient(const ImageRGB& image,
                         const std::vector<float>& dlogits);

  // Device images (HWC floats in [0,1], width * height * 3 values): the
  // forward pass always runs. dimage_hwc gets dLoss/dImage (device, same
  // layout).
  std::vector<float> LogitsDevice(const float* image_hwc, int width,
                                  int height);
  void InputGradientDevice(const float* image_hwc, int width, int height,
                           const std::vector<float>& dlogits,
                           float* dimage_hwc);

 private:
  // Network input from a width x height device HWC patch with rows `pitch`
  // pixels apart, then the forward pass.
  std::vector<float> ForwardDevice(const float* image_hwc, int width,
                                   int height, int pitch) override;
  // Backward to the network input, then into dimage_hwc (same patch layout),
  // overwriting or adding.
  void BackwardDevice(const std::vector<float>& dlogits, float* dimage_hwc,
                      int pitch, bool accumulate) override;

  // The handles (declared first: the network's layers point into it).
  std::unique_ptr<CudaNnContext> context_;
  std::unique_ptr<CudaHiddenDecoder> network_;
  // Network input and the gradients.
  DeviceTensor input_, dlogits_, dinput_;
};

}  // namespace watergs
