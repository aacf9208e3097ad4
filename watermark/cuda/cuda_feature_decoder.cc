// The random-feature decoder on the GPU (see cuda_feature_decoder.h).
#include "watermark/cuda/cuda_feature_decoder.h"

#include <cstring>
#include <string>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/error.h"
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
      conv_(std::make_unique<CudaConv2d>(context_.get(), net.conv)),
      linear_(std::make_unique<CudaLinear>(context_.get(), net.linear)) {}

CudaFeatureDecoder::~CudaFeatureDecoder() = default;

void CudaFeatureDecoder::ForwardDevice(const float* image_hwc, int width,
                                       int height, int pitch) {
  const int p = config_.pool;
  // FeatureNet::Forward's check and message.
  if (width < p || height < p)
    Fail("feature decoder: input of " + std::to_string(width) + "x" +
         std::to_string(height) + " pixels (3 channels) is smaller than its " +
         std::to_string(p) + "x" + std::to_string(p) + " pooling");
  width_ = width;
  height_ = height;
  pooled_.Resize(1, 3, height / p, width / p);
  WATERGS_CUDA_CHECK(feature_kernels::ImageToPooledInput(
      image_hwc, width, height, pitch, p, pooled_.ptr()));
  conv_->Forward(pooled_, &conv_out_);
  features_.Resize(1, config_.channels, 1, 1);
  WATERGS_CUDA_CHECK(feature_kernels::ReluGlobalAvgPool(
      conv_out_.ptr(), config_.channels, conv_out_.PlaneSize(),
      features_.ptr()));
  linear_->Forward(features_, &logits_dev_);
  logits_dev_.data.Download(&logits_);
  logits_.resize(config_.num_bits);
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
  conv_->Backward(pooled_, dconv_, &dpooled_, false);
  WATERGS_CUDA_CHECK(feature_kernels::PooledGradientToImage(
      dpooled_.ptr(), width_, height_, pitch, config_.pool, accumulate,
      dimage_hwc));
}

void CudaFeatureDecoder::ForwardIfNeeded(const ImageRGB& image) {
  const size_t count = image.data.size();
  if (image.width <= 0 || image.height <= 0 ||
      count != size_t(image.width) * image.height * 3)
    Fail("decoder: image of " + std::to_string(image.width) + "x" +
         std::to_string(image.height) + " with " + std::to_string(count) +
         " values");
  if (has_forward_ && cached_width_ == image.width &&
      cached_height_ == image.height &&
      std::memcmp(cached_pixels_.data(), image.data.data(),
                  count * sizeof(float)) == 0)
    return;
  // Invalid until the pass completes: a failed pass must not leave the old
  // logits answering for the new image.
  has_forward_ = patch_forward_ = false;
  image_.Upload(image.data);
  ForwardDevice(image_.data(), image.width, image.height, image.width);
  cached_pixels_.assign(image.data.begin(), image.data.end());
  cached_width_ = image.width;
  cached_height_ = image.height;
  has_forward_ = true;
}

std::vector<float> CudaFeatureDecoder::Logits(const ImageRGB& image) {
  ForwardIfNeeded(image);
  return logits_;
}

void CudaFeatureDecoder::InputGradient(const ImageRGB& image,
                                       const std::vector<float>& dlogits,
                                       ImageRGB* dimage) {
  CheckLogitGradients(dlogits.size());
  ForwardIfNeeded(image);
  dimage_.Resize(image.data.size());
  BackwardDevice(dlogits, dimage_.data(), image.width, false);
  dimage_.Download(&dimage->data);
  dimage->width = image.width;
  dimage->height = image.height;
}

namespace {

// Checks that `rect` lies in an image `pitch` pixels wide (its height is the
// caller's to check) and returns the offset of its first value.
size_t PatchOffset(int pitch, const PixelRect& rect) {
  if (rect.width <= 0 || rect.height <= 0 || rect.x0 < 0 || rect.y0 < 0 ||
      rect.x0 + rect.width > pitch) {
    Fail("decoder: patch " + std::to_string(rect.width) + "x" +
         std::to_string(rect.height) + " at (" + std::to_string(rect.x0) +
         ", " + std::to_string(rect.y0) + ") outside an image " +
         std::to_string(pitch) + " pixels wide");
  }
  return (size_t(rect.y0) * pitch + rect.x0) * 3;
}

}  // namespace

std::vector<float> CudaFeatureDecoder::LogitsDevicePatch(
    const float* image_hwc, int pitch, const PixelRect& rect) {
  const size_t offset = PatchOffset(pitch, rect);
  has_forward_ = patch_forward_ = false;
  ForwardDevice(image_hwc + offset, rect.width, rect.height, pitch);
  patch_forward_ = true;
  patch_ = rect;
  return logits_;
}

void CudaFeatureDecoder::AddInputGradientDevicePatch(
    const std::vector<float>& dlogits, float* dimage_hwc, int pitch,
    const PixelRect& rect) {
  if (!patch_forward_ || rect.x0 != patch_.x0 || rect.y0 != patch_.y0 ||
      rect.width != patch_.width || rect.height != patch_.height) {
    Fail(
        "decoder: input gradient of a patch the last forward pass did not "
        "decode");
  }
  BackwardDevice(dlogits, dimage_hwc + PatchOffset(pitch, rect), pitch, true);
}

}  // namespace watergs
