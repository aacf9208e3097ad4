// The random-feature decoder on the GPU (see cuda_feature_decoder.h).
#include "watermark/cuda/cuda_feature_decoder.h"

#include <algorithm>
#include <string>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/util/error.h"
#include "watermark/cuda/feature_kernels.h"
#include "watermark/network_file.h"

namespace watergs {

std::unique_ptr<CudaFeatureDecoder> CudaFeatureDecoder::Load(
    const std::string& path, int expected_bits, bool allow_tf32) {
  const std::unique_ptr<FeatureNet> net =
      FeatureNetFromFile(path, ReadNetworkFile(path), expected_bits);
  return std::make_unique<CudaFeatureDecoder>(*net, allow_tf32);
}

CudaFeatureDecoder::CudaFeatureDecoder(FeatureNet& net, bool allow_tf32)
    : config_(net.config()),
      context_(std::make_unique<CudaNnContext>(allow_tf32)),
      linear_(std::make_unique<CudaLinear>(context_.get(), net.linear)) {
  if (config_.highpass > 0)
    Fail("feature decoder: the high-pass front end (highpass " +
         std::to_string(config_.highpass) +
         ") has no CUDA kernel yet; decode with --device cpu");
  const int taps = ConvTaps(), channels = config_.channels;
  const std::vector<float>& w = net.conv.weight.value;
  const std::vector<float>& b = net.conv.bias.value;
  if (w.size() != size_t(channels) * taps || b.size() != size_t(channels))
    Fail("feature decoder: conv weights of " + std::to_string(w.size()) +
         " values and bias of " + std::to_string(b.size()) + ", expected " +
         std::to_string(size_t(channels) * taps) + " and " +
         std::to_string(channels));
  std::vector<float> rows(size_t(channels) * (taps + 1));
  for (int c = 0; c < channels; ++c) {
    std::copy_n(w.begin() + size_t(c) * taps, taps,
                rows.begin() + size_t(c) * (taps + 1));
    rows[size_t(c) * (taps + 1) + taps] = b[c];
  }
  conv_weights_.Upload(rows);
}

CudaFeatureDecoder::~CudaFeatureDecoder() = default;

std::vector<float> CudaFeatureDecoder::ForwardDevice(const float* image_hwc,
                                                     int width, int height,
                                                     int pitch) {
  const int p = config_.pool;
  // FeatureNet::Forward's check and message.
  if (width < p || height < p)
    Fail("feature decoder: input of " + std::to_string(width) + "x" +
         std::to_string(height) + " pixels (3 channels) is smaller than its " +
         std::to_string(p) + "x" + std::to_string(p) + " pooling");
  width_ = width;
  height_ = height;
  const int ph = height / p, pw = width / p, k = config_.kernel;
  const int taps = ConvTaps(), plane = ph * pw;
  pooled_.Resize(1, 3, ph, pw);
  WATERGS_CUDA_CHECK(feature_kernels::ImageToPooledInput(
      image_hwc, width, height, pitch, p, pooled_.ptr()));
  cols_.Resize(size_t(taps + 1) * plane);
  WATERGS_CUDA_CHECK(
      feature_kernels::Im2Col(pooled_.ptr(), 3, ph, pw, k, cols_.data()));
  // Row-major conv [channels, plane] = W [channels, taps + 1] cols; in
  // cuBLAS's column-major terms conv^T = cols^T W^T. With TF32 allowed the
  // bias, folded in, is rounded to TF32 too (decoder_benchmark only).
  conv_out_.Resize(1, config_.channels, ph, pw);
  const float one = 1.f, zero = 0.f;
  WATERGS_CUBLAS_CHECK(cublasSgemm(context_->cublas(), CUBLAS_OP_N, CUBLAS_OP_N,
                                   plane, config_.channels, taps + 1, &one,
                                   cols_.data(), plane, conv_weights_.data(),
                                   taps + 1, &zero, conv_out_.ptr(), plane));
  features_.Resize(1, config_.channels, 1, 1);
  WATERGS_CUDA_CHECK(feature_kernels::ReluGlobalAvgPool(
      conv_out_.ptr(), config_.channels, conv_out_.PlaneSize(),
      features_.ptr()));
  linear_->Forward(features_, &logits_dev_);
  std::vector<float> logits;
  logits_dev_.data.Download(&logits);
  logits.resize(config_.num_bits);
  return logits;
}

void CudaFeatureDecoder::BackwardDevice(const std::vector<float>& dlogits,
                                        float* dimage_hwc, int pitch,
                                        bool accumulate) {
  CheckLogitGradients(dlogits.size());
  dlogits_.Resize(1, config_.num_bits, 1, 1);
  dlogits_.data.Upload(dlogits);
  linear_->Backward(features_, dlogits_, &dfeatures_, false);
  dconv_.ResizeLike(conv_out_);
  WATERGS_CUDA_CHECK(feature_kernels::ReluGlobalAvgPoolBackward(
      dfeatures_.ptr(), conv_out_.ptr(), config_.channels,
      conv_out_.PlaneSize(), dconv_.ptr()));
  // dcols [taps, plane] = W[:, :taps]^T dconv: dcols^T = dconv^T W[:, :taps].
  const int taps = ConvTaps(), plane = int(conv_out_.PlaneSize());
  const float one = 1.f, zero = 0.f;
  dcols_.Resize(size_t(taps) * plane);
  WATERGS_CUBLAS_CHECK(cublasSgemm(context_->cublas(), CUBLAS_OP_N, CUBLAS_OP_T,
                                   plane, taps, config_.channels, &one,
                                   dconv_.ptr(), plane, conv_weights_.data(),
                                   taps + 1, &zero, dcols_.data(), plane));
  dpooled_.ResizeLike(pooled_);
  WATERGS_CUDA_CHECK(feature_kernels::Col2Im(
      dcols_.data(), 3, pooled_.h, pooled_.w, config_.kernel, dpooled_.ptr()));
  WATERGS_CUDA_CHECK(feature_kernels::PooledGradientToImage(
      dpooled_.ptr(), width_, height_, pitch, config_.pool, accumulate,
      dimage_hwc));
}

}  // namespace watergs
