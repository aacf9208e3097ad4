// The embedding iteration Embedder (embedder.h) drives when the model, its
// Adam moments and the gradients live on an accelerator (the CUDA one:
// cuda/cuda_embedding_step.h). The embedder's host model and Adam are the
// step's mirror: Pull* brings them up to date before the host reads them,
// MarkHostEdited says the host replaced them (a resume). Kept free of CUDA
// types so that the embedder compiles the same with or without the backend.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "distortion/distortion_layer.h"
#include "gaussian/adam.h"
#include "gaussian/camera.h"
#include "gaussian/density_strategy.h"
#include "gaussian/image.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// What the forward half of one iteration renders and decodes.
struct DeviceEmbedView {
  RenderCamera camera;
  // options.rect is the rendered region (empty = the whole frame).
  RenderOptions options;
  // Ground truth of the rendered region (host, its size).
  const ImageRGB* truth = nullptr;
  // The decoded patch in rendered-region pixels; empty = all of it.
  PixelRect decoder_crop;
  // The sampled distortion layer (null or identity: the model itself).
  const DistortionLayer* layer = nullptr;
  // The unwatermarked model's logits of the same patch (the owner's
  // reading, see MessageBce); null: the blind reading.
  const std::vector<float>* reference_logits = nullptr;
};

// Figures of the forward half.
struct DeviceEmbedLoss {
  LossTerms image;
  double bce = 0;
  int bit_errors = 0;
  // Seconds of the distortion, the render, the image loss and the decoder.
  double distortion_s = 0, render_s = 0, image_loss_s = 0, decoder_s = 0;
};

class DeviceEmbeddingStep {
 public:
  virtual ~DeviceEmbeddingStep() = default;
  // Inria's density control on the device, continuing from `state` (the
  // host strategy's SaveState for the current model).
  virtual void TakeDensityControl(const DensityOptions& options,
                                  double scene_extent,
                                  const std::string& state) = 0;
  // Distorts, renders, and evaluates (1 - beta) L1 + beta D-SSIM and the
  // BCE of the decoded crop, keeping their image gradient on the device.
  virtual DeviceEmbedLoss Forward(const DeviceEmbedView& view,
                                  std::mt19937_64& rng) = 0;
  // Backward of the last Forward, scattered through the distortion; then
  // density control at 1-based `iteration` (if taken) and, unless it
  // densified, Adam. The event's parent list is filled when it densified.
  // `backward_s`, `density_s`, `adam_s` get the stages' seconds.
  virtual DensityEvent BackwardAndUpdate(int64_t iteration, double* backward_s,
                                         double* density_s, double* adam_s) = 0;
  // Renders the device model (whole-model checks without pulling it).
  virtual void Render(const RenderCamera& camera, const RenderOptions& options,
                      ImageRGB* image) = 0;
  // Device -> host copies when the host ones are behind; the host Adam is
  // re-sized to the device's Gaussian count.
  virtual void PullModel() = 0;
  virtual void PullAdam() = 0;
  // The host model and Adam were replaced: rebuilt on the device next use.
  virtual void MarkHostEdited() = 0;
  // Gaussians in the model (the device copy or, when behind, the host one).
  virtual size_t NumGaussians() const = 0;
  // The density state as the CPU strategy's SaveState writes it, and back.
  virtual std::string SaveDensityState() const = 0;
  virtual void LoadDensityState(const std::string& state) = 0;
};

// Makes a device step mirroring `host_model` and `host_adam` (the
// embedder's), or null for the host path.
using DeviceEmbeddingStepFactory =
    std::function<std::unique_ptr<DeviceEmbeddingStep>(
        GaussianModel* host_model, Adam* host_adam)>;

}  // namespace watergs
