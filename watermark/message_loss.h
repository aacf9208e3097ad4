// The message term of the embedding: the decoder's BCE on a render (with
// the logit margin and the owner's reference logits), its gradient on the
// image and, through the rasterizer's public interface, on the model; and
// the crop/patch copies the terms read and write. Shared by the host
// embedding step, the concatenated encoder and their tests.
#pragma once

#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/rasterizer.h"
#include "watermark/bit_decoder.h"

namespace watergs {

// Adds scale * `patch` into `target` at rect's offset (patch: rect's size).
void AddPatch(const ImageRGB& patch, const PixelRect& rect, float scale,
              ImageRGB* target);

// Copies rect of `image` into `out` (resized).
void CropImage(const ImageRGB& image, const PixelRect& rect, ImageRGB* out);

// The message term on decoded logits: returns BCE(targets, logits) (mean
// over the bits) and sets dlogits = gamma * dBCE/dlogits; bit_errors (if not
// null) gets the errors of the decoded bits. margin > 0 moves each logit by
// margin towards the wrong side before the BCE (the bit errors are the
// logits' own). `reference` (the unwatermarked model's logits at the same
// view) is subtracted first: the owner's reading, bits and errors included.
// Error if the lengths differ.
// With a reference, `blind` (weight > 0) adds weight * BCE of the blind
// reading (the logits themselves, moved by blind.margin) to the loss and its
// gradient: one embedding both readers find (embed --reading both); the
// bit errors stay the owner's.
struct BlindTerm {
  double weight = 0;
  double margin = 0;
};
double MessageBce(const std::vector<float>& logits,
                  const std::vector<float>& targets, double gamma,
                  std::vector<float>* dlogits, int* bit_errors,
                  double margin = 0,
                  const std::vector<float>* reference = nullptr,
                  const BlindTerm& blind = {});

// The message term on a render: returns BCE(targets, D(image[crop])) (crop
// in image pixels, empty = all of it) and adds gamma * d BCE / d image into
// grad_image (image's shape); bit_errors (if not null) gets the errors of
// the decoded bits.
// margin > 0 moves each logit by margin towards the wrong side first;
// `reference` logits are subtracted before (see MessageBce).
double AddMessageLoss(BitDecoder& decoder, const ImageRGB& image,
                      const PixelRect& crop, const std::vector<float>& targets,
                      double gamma, ImageRGB* grad_image, int* bit_errors,
                      double margin = 0,
                      const std::vector<float>* reference = nullptr,
                      const BlindTerm& blind = {});

// gamma * BCE(targets, D(render(model)[crop])) and its gradient w.r.t. the
// model, the render taken over options.rect (as Step does); for checks.
// AddMessageLoss read through a JPEG round trip at `quality` (1-100) of the
// crop: loss and logits are those of the compressed crop, and its image
// gradient is added at the crop unchanged (straight-through estimator: the
// quantisation has no useful derivative; MBRS and StegaStamp train so).
double AddJpegMessageLoss(BitDecoder& decoder, const ImageRGB& image,
                          const PixelRect& crop, int quality,
                          const std::vector<float>& targets, double gamma,
                          ImageRGB* grad_image, int* bit_errors, double margin,
                          const std::vector<float>* reference,
                          const BlindTerm& blind = {});

double MessageLossGradient(Rasterizer& rasterizer, const GaussianModel& model,
                           const RenderCamera& camera,
                           const RenderOptions& options, const PixelRect& crop,
                           BitDecoder& decoder,
                           const std::vector<float>& targets, double gamma,
                           GaussianGradients* grads);

}  // namespace watergs
