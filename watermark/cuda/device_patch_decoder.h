// A BitDecoder on the GPU that the device-resident embedding step
// (cuda_embedding_step.h) can read in place: the logits of a patch of a
// device image and the patch's input gradient added into a device gradient
// image, with no crop copy. Implemented by CudaDecoder (HiDDeN,
// cuda_hidden.h) and CudaFeatureDecoder (the random-feature decoder,
// cuda_feature_decoder.h).
#pragma once

#include <vector>

#include "gaussian/rasterizer.h"
#include "watermark/bit_decoder.h"

namespace watergs {

class DevicePatchDecoder : public BitDecoder {
 public:
  // The logits of the `rect` patch of a device HWC image (values in [0, 1])
  // whose rows are `pitch` pixels apart; the rect's height is the caller's
  // to check.
  virtual std::vector<float> LogitsDevicePatch(const float* image_hwc,
                                               int pitch,
                                               const PixelRect& rect) = 0;
  // With no decoder call since LogitsDevicePatch of the same rect: adds
  // dLoss/dPatch for `dlogits` into that rect of `dimage_hwc` (same layout).
  virtual void AddInputGradientDevicePatch(const std::vector<float>& dlogits,
                                           float* dimage_hwc, int pitch,
                                           const PixelRect& rect) = 0;

 protected:
  DevicePatchDecoder() = default;
  DevicePatchDecoder(DevicePatchDecoder&&) = default;
  DevicePatchDecoder& operator=(DevicePatchDecoder&&) = default;
};

}  // namespace watergs
