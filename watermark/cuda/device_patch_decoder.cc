// The host interface and patch bookkeeping of the GPU decoders (see
// device_patch_decoder.h).
#include "watermark/cuda/device_patch_decoder.h"

#include <cstring>
#include <string>
#include <utility>

#include "gaussian/util/error.h"

namespace watergs {
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

DevicePatchDecoder::DevicePatchDecoder(DevicePatchDecoder&& other) noexcept {
  *this = std::move(other);
}

DevicePatchDecoder& DevicePatchDecoder::operator=(
    DevicePatchDecoder&& other) noexcept {
  image_ = std::move(other.image_);
  dimage_ = std::move(other.dimage_);
  cached_pixels_ = std::move(other.cached_pixels_);
  logits_ = std::move(other.logits_);
  cached_width_ = other.cached_width_;
  cached_height_ = other.cached_height_;
  has_forward_ = other.has_forward_ = false;
  patch_forward_ = other.patch_forward_ = false;
  return *this;
}

void DevicePatchDecoder::ForwardIfNeeded(const ImageRGB& image) {
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
  logits_ =
      ForwardDevice(image_.data(), image.width, image.height, image.width);
  cached_pixels_.assign(image.data.begin(), image.data.end());
  cached_width_ = image.width;
  cached_height_ = image.height;
  has_forward_ = true;
}

std::vector<float> DevicePatchDecoder::Logits(const ImageRGB& image) {
  ForwardIfNeeded(image);
  return logits_;
}

void DevicePatchDecoder::InputGradient(const ImageRGB& image,
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

std::vector<float> DevicePatchDecoder::ForwardUncached(const float* image_hwc,
                                                       int width, int height) {
  if (width <= 0 || height <= 0)
    Fail("decoder: image of " + std::to_string(width) + "x" +
         std::to_string(height));
  // The activations will no longer be those of the cached host image or of a
  // patch.
  has_forward_ = patch_forward_ = false;
  logits_ = ForwardDevice(image_hwc, width, height, width);
  return logits_;
}

std::vector<float> DevicePatchDecoder::LogitsDevicePatch(
    const float* image_hwc, int pitch, const PixelRect& rect) {
  const size_t offset = PatchOffset(pitch, rect);
  has_forward_ = patch_forward_ = false;
  logits_ = ForwardDevice(image_hwc + offset, rect.width, rect.height, pitch);
  patch_forward_ = true;
  patch_ = rect;
  return logits_;
}

void DevicePatchDecoder::AddInputGradientDevicePatch(
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
