// The random-feature decoder (feature_decoder.h, the shipped default) on the
// GPU, loaded from the same weights file:
//   D(x) = A . GAP(ReLU(conv_k(avgpool_p(2x - 1)))) + b
// with the average pooling fused into the image -> network-input kernel, the
// k x k convolution as one cuBLAS GEMM over an im2col matrix (3 k^2 + 1 rows:
// with 3 input channels cuDNN's heuristic picks ran 3.4 ms a forward and
// input gradient at 240x180 on an H200), ReLU and global pooling fused into
// one kernel (and its backward into one), and the projection through cuBLAS.
// Logits and input gradient for host images (BitDecoder) and in place on a
// patch of a device image (DevicePatchDecoder, for the device-resident
// embedding step). Parity with the CPU decoder:
// tests/watermark/cuda_feature_decoder_test.cc.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gaussian/cuda/device_buffer.h"
#include "watermark/cuda/cuda_nn.h"
#include "watermark/cuda/device_patch_decoder.h"
#include "watermark/feature_decoder.h"

namespace watergs {

class CudaFeatureDecoder : public DevicePatchDecoder {
 public:
  // Loads a weights file with FeatureNetFromFile's checks and errors.
  // allow_tf32: see CudaNnContext (parity tests and LoadBitDecoder: false).
  static std::unique_ptr<CudaFeatureDecoder> Load(const std::string& path,
                                                  int expected_bits = 0,
                                                  bool allow_tf32 = false);
  // Copies the weights of `net` (which may then go away).
  explicit CudaFeatureDecoder(FeatureNet& net, bool allow_tf32 = false);
  ~CudaFeatureDecoder() override;
  CudaFeatureDecoder(const CudaFeatureDecoder&) = delete;
  CudaFeatureDecoder& operator=(const CudaFeatureDecoder&) = delete;

  // Images of at least pool x pool pixels (Logits, InputGradient).
  int NumBits() const override { return config_.num_bits; }

 private:
  // Pooled network input from a width x height device HWC patch with rows
  // `pitch` pixels apart, then the forward pass.
  std::vector<float> ForwardDevice(const float* image_hwc, int width,
                                   int height, int pitch) override;
  // Backward of the last forward pass into dimage_hwc (the same patch
  // layout), overwriting or adding.
  void BackwardDevice(const std::vector<float>& dlogits, float* dimage_hwc,
                      int pitch, bool accumulate) override;
  // Values in one convolution window: 3 k^2.
  int ConvTaps() const { return 3 * config_.kernel * config_.kernel; }

  FeatureDecoderConfig config_;
  // The handles (declared before the layers that point into them).
  std::unique_ptr<CudaNnContext> context_;
  // Convolution weights [channels, 3 k^2 + 1] (the bias last in each row).
  DeviceBuffer<float> conv_weights_;
  std::unique_ptr<CudaLinear> linear_;
  // Activations of the last forward pass and gradient scratch.
  DeviceTensor pooled_, conv_out_, features_, logits_dev_, dlogits_, dfeatures_,
      dconv_, dpooled_;
  // im2col matrix of pooled_ and its gradient (Im2Col).
  DeviceBuffer<float> cols_, dcols_;
  // Size of the last forward pass's patch.
  int width_ = 0, height_ = 0;
};

}  // namespace watergs
