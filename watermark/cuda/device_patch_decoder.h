// A BitDecoder on the GPU that the device-resident embedding step
// (cuda_embedding_step.h) can read in place: the logits of a patch of a
// device image and the patch's input gradient added into a device gradient
// image, with no crop copy. The host interface (an uploaded image, its forward
// pass cached) and the patch bookkeeping live here; a network supplies its
// forward and backward passes on a device patch: CudaDecoder (HiDDeN,
// cuda_hidden.h) and CudaFeatureDecoder (the random-feature decoder,
// cuda_feature_decoder.h).
#pragma once

#include <vector>

#include "gaussian/cuda/device_buffer.h"
#include "gaussian/rasterizer.h"
#include "watermark/bit_decoder.h"

namespace watergs {

class DevicePatchDecoder : public BitDecoder {
 public:
  // image -> L logits; the forward pass runs only when `image` differs from
  // the last host image decoded.
  std::vector<float> Logits(const ImageRGB& image) override;
  // dLoss/dImage of `dlogits` (L values), image-sized; the forward pass as in
  // Logits.
  void InputGradient(const ImageRGB& image, const std::vector<float>& dlogits,
                     ImageRGB* dimage) override;
  // The logits of the `rect` patch of a device HWC image (values in [0, 1])
  // whose rows are `pitch` pixels apart; the rect's height is the caller's
  // to check.
  std::vector<float> LogitsDevicePatch(const float* image_hwc, int pitch,
                                       const PixelRect& rect);
  // With no decoder call since LogitsDevicePatch of the same rect: adds
  // dLoss/dPatch for `dlogits` into that rect of `dimage_hwc` (same layout).
  void AddInputGradientDevicePatch(const std::vector<float>& dlogits,
                                   float* dimage_hwc, int pitch,
                                   const PixelRect& rect);

 protected:
  DevicePatchDecoder() = default;
  // Moves the buffers and drops the cached forward pass of both sides (a
  // network may keep pointers into the source's activations).
  DevicePatchDecoder(DevicePatchDecoder&& other) noexcept;
  DevicePatchDecoder& operator=(DevicePatchDecoder&& other) noexcept;

  // The forward pass on a width x height device HWC patch whose rows are
  // `pitch` pixels apart: its L logits.
  virtual std::vector<float> ForwardDevice(const float* image_hwc, int width,
                                           int height, int pitch) = 0;
  // The backward pass of the last ForwardDevice into dimage_hwc (the same
  // patch layout), overwriting or adding.
  virtual void BackwardDevice(const std::vector<float>& dlogits,
                              float* dimage_hwc, int pitch,
                              bool accumulate) = 0;
  // The forward pass on a whole device image, cached for neither the host
  // interface nor a patch.
  std::vector<float> ForwardUncached(const float* image_hwc, int width,
                                     int height);

 private:
  // Runs the forward pass unless `image` is the cached host image.
  void ForwardIfNeeded(const ImageRGB& image);

  // Uploaded host image and its gradient (HWC).
  DeviceBuffer<float> image_, dimage_;
  // The host image of the last forward pass, its size, and the logits of the
  // last forward pass.
  std::vector<float> cached_pixels_, logits_;
  int cached_width_ = 0, cached_height_ = 0;
  // Whether the activations are of the cached host image, or of a
  // LogitsDevicePatch call (and its rect).
  bool has_forward_ = false, patch_forward_ = false;
  PixelRect patch_;
};

}  // namespace watergs
