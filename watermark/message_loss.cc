// The message term of the embedding (see message_loss.h).
#include "watermark/message_loss.h"

#include <cstring>
#include <memory>
#include <string>

#include "gaussian/util/error.h"
#include "watermark/image_attacks.h"
#include "watermark/nn_layers.h"
#include "watermark/tensor.h"

namespace watergs {

void AddPatch(const ImageRGB& patch, const PixelRect& rect, float scale,
              ImageRGB* target) {
  for (int y = 0; y < rect.height; ++y) {
    const float* src = patch.At(0, y);
    float* dst = target->At(rect.x0, rect.y0 + y);
    for (int k = 0; k < 3 * rect.width; ++k) dst[k] += scale * src[k];
  }
}

void CropImage(const ImageRGB& image, const PixelRect& rect, ImageRGB* out) {
  out->width = rect.width;
  out->height = rect.height;
  out->data.resize(size_t(rect.width) * rect.height * 3);
  for (int y = 0; y < rect.height; ++y) {
    std::memcpy(out->At(0, y), image.At(rect.x0, rect.y0 + y),
                sizeof(float) * 3 * rect.width);
  }
}

double MessageBce(const std::vector<float>& logits,
                  const std::vector<float>& targets, double gamma,
                  std::vector<float>* dlogits, int* bit_errors, double margin,
                  const std::vector<float>* reference, const BlindTerm& blind) {
  if (logits.size() != targets.size() ||
      (reference && reference->size() != targets.size())) {
    Fail("message loss: the decoder reads " + std::to_string(logits.size()) +
         " bits, the message has " + std::to_string(targets.size()));
  }
  Tensor logit_tensor(1, static_cast<int>(logits.size()), 1, 1);
  logit_tensor.data = logits;
  if (reference) {
    for (size_t i = 0; i < logits.size(); ++i) {
      logit_tensor.data[i] -= (*reference)[i];
    }
  }
  // The bits read (before the margin moves them).
  const std::vector<float> read = logit_tensor.data;
  for (size_t i = 0; i < logits.size(); ++i) {
    logit_tensor.data[i] -= float(margin) * (targets[i] > 0.5f ? 1.f : -1.f);
  }
  Tensor grad;
  const double bce = BceWithLogits(logit_tensor, targets, &grad);
  if (bit_errors) {
    *bit_errors = 0;
    for (size_t i = 0; i < targets.size(); ++i) {
      *bit_errors += (read[i] > 0) != (targets[i] > 0.5f);
    }
  }
  for (float& g : grad.data) g *= static_cast<float>(gamma);
  *dlogits = std::move(grad.data);
  if (reference && blind.weight > 0) {
    std::vector<float> blind_grad;
    const double blind_bce = MessageBce(logits, targets, gamma * blind.weight,
                                        &blind_grad, nullptr, blind.margin);
    for (size_t i = 0; i < blind_grad.size(); ++i) {
      (*dlogits)[i] += blind_grad[i];
    }
    return bce + blind.weight * blind_bce;
  }
  return bce;
}

double AddMessageLoss(BitDecoder& decoder, const ImageRGB& image,
                      const PixelRect& crop, const std::vector<float>& targets,
                      double gamma, ImageRGB* grad_image, int* bit_errors,
                      double margin, const std::vector<float>* reference,
                      const BlindTerm& blind) {
  ImageRGB cropped, grad;
  if (!crop.empty()) CropImage(image, crop, &cropped);
  const ImageRGB& decoded = crop.empty() ? image : cropped;
  const std::vector<float> logits = decoder.Logits(decoded);
  std::vector<float> dlogits;
  const double bce = MessageBce(logits, targets, gamma, &dlogits, bit_errors,
                                margin, reference, blind);
  decoder.InputGradient(decoded, dlogits, &grad);
  AddPatch(grad,
           crop.empty() ? PixelRect{0, 0, image.width, image.height} : crop,
           1.f, grad_image);
  return bce;
}

double AddJpegMessageLoss(BitDecoder& decoder, const ImageRGB& image,
                          const PixelRect& crop, int quality,
                          const std::vector<float>& targets, double gamma,
                          ImageRGB* grad_image, int* bit_errors, double margin,
                          const std::vector<float>* reference,
                          const BlindTerm& blind) {
  const PixelRect region =
      crop.empty() ? PixelRect{0, 0, image.width, image.height} : crop;
  ImageRGB cropped;
  if (!crop.empty()) CropImage(image, crop, &cropped);
  ImageAttackSpec jpeg;
  jpeg.kind = ImageAttackKind::kJpeg;
  jpeg.value = quality;
  const ImageRGB compressed =
      ApplyImageAttack(jpeg, crop.empty() ? image : cropped);
  ImageRGB grad(compressed.width, compressed.height);
  const double bce =
      AddMessageLoss(decoder, compressed, PixelRect{}, targets, gamma, &grad,
                     bit_errors, margin, reference, blind);
  // Straight-through: d JPEG(x) / dx taken as the identity.
  AddPatch(grad, region, 1.f, grad_image);
  return bce;
}

double MessageLossGradient(Rasterizer& rasterizer, const GaussianModel& model,
                           const RenderCamera& camera,
                           const RenderOptions& options, const PixelRect& crop,
                           BitDecoder& decoder,
                           const std::vector<float>& targets, double gamma,
                           GaussianGradients* grads) {
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  rasterizer.Forward(model, camera, options, &image, &context);
  ImageRGB grad_image(image.width, image.height);
  const double bce = AddMessageLoss(decoder, image, crop, targets, gamma,
                                    &grad_image, nullptr);
  if (grads) rasterizer.Backward(model, *context, grad_image, grads);
  return gamma * bce;
}

}  // namespace watergs
