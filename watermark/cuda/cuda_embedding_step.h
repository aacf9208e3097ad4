// One WATER-GS fine-tuning iteration (embedder.h) with everything per
// Gaussian on the GPU: the model and its Adam moments (a CudaModelMirror of
// the embedder's host copies), the 3D distortion layer and the gradient
// scatter back through it, the render of the crop, the image loss, the
// decoder's forward and input gradient on the render (in place, no crop
// copy), the backward pass, Inria's density control and Adam. Per
// iteration only the ground-truth crop goes up and the L logits and three
// loss figures come down; the Gaussians' origin list comes down at a
// densification. Embedder uses it when its rasterizer is a CudaRasterizer,
// its decoder a CUDA one (DevicePatchDecoder: CudaDecoder or
// CudaFeatureDecoder), its moments float32, and neither decoder jitter nor
// an MSE term is on (Embedder::host_step_reason says which keeps the host
// step). The logit margin is applied as on the host (MessageBce).
//
// Same results as the host step up to float rounding, except: the noise
// and dropout layers draw their samples on the device (cuda_distortion.h:
// same distributions, other samples and rng use), and under position noise
// density control's screen radii are those of the noisy render (the host
// step projects the undistorted model); crop and identity are exact.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "distortion/cuda/cuda_distortion.h"
#include "distortion/distortion_layer.h"
#include "gaussian/adam.h"
#include "gaussian/camera.h"
#include "gaussian/cuda/cuda_density.h"
#include "gaussian/cuda/cuda_loss.h"
#include "gaussian/cuda/cuda_model_mirror.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/density_strategy.h"
#include "gaussian/image.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"
#include "watermark/cuda/device_patch_decoder.h"
#include "watermark/device_embedding_step.h"

namespace watergs {

class CudaEmbeddingStep : public DeviceEmbeddingStep {
 public:
  // `rasterizer`, `decoder`, `host_model` and `host_adam` (the embedder's)
  // must outlive this; targets holds the message's 0/1 bits. mse_weight > 0:
  // the image term is that times the MSE (as the host's), else (1 - beta) L1
  // + beta D-SSIM.
  CudaEmbeddingStep(CudaRasterizer* rasterizer, DevicePatchDecoder* decoder,
                    const AdamOptions& adam_options, double scene_extent,
                    double beta, double gamma, double margin,
                    std::vector<float> targets, GaussianModel* host_model,
                    Adam* host_adam, double mse_weight = 0);
  ~CudaEmbeddingStep() override;

  // DeviceEmbeddingStep. Forward draws from rng as the host step does
  // (see above for noise and dropout).
  void TakeDensityControl(const DensityOptions& options, double scene_extent,
                          const std::string& state) override;
  DeviceEmbedLoss Forward(const DeviceEmbedView& view,
                          std::mt19937_64& rng) override;
  DensityEvent BackwardAndUpdate(int64_t iteration, double* backward_s,
                                 double* density_s, double* adam_s) override;
  void Render(const RenderCamera& camera, const RenderOptions& options,
              ImageRGB* image) override;
  void PullModel() override { mirror_.PullModel(); }
  void PullAdam() override { mirror_.PullAdam(); }
  void MarkHostEdited() override;
  size_t NumGaussians() const override { return mirror_.NumGaussians(); }
  std::string SaveDensityState() const override;
  void LoadDensityState(const std::string& state) override;

 private:
  // Sizes and wires the N-row gradient arrays (dense SH).
  CudaGradientArrays Gradients(size_t n, int rest_stride,
                               DeviceBuffer<float> (&buffers)[8],
                               DeviceBuffer<uint8_t>* visible);
  // Adds the distorted render's gradients into the model's rows.
  void ScatterToModel(size_t n_distorted);
  // The device layer twin of a host layer (made on first use).
  CudaDistortionLayer& DeviceLayer(const DistortionLayer& layer);

  CudaRasterizer* rasterizer_;
  DevicePatchDecoder* decoder_;
  CudaModelMirror mirror_;
  CudaTrainingLoss loss_;
  double gamma_;
  double margin_;  // see MessageBce
  double mse_weight_;
  std::vector<float> targets_;
  // A device twin per layer spec (ToString): keyed by spec, not by the host
  // layer's address, which a sampler rebuilt mid-run (embed --distortions
  // auto) may hand to another layer.
  std::map<std::string, std::unique_ptr<CudaDistortionLayer>> layers_;
  // The distorted model of this iteration and each row's source row.
  DeviceGaussianArrays distorted_;
  DeviceBuffer<uint32_t> source_;
  bool distorted_this_step_ = false;
  // Gradients of the model and of the distorted model: means, log-scales,
  // quats, opacity, sh_dc, sh_rest, |dmean2d| px and NDC; visibility.
  DeviceBuffer<float> grads_[8], distorted_grads_[8];
  DeviceBuffer<uint8_t> visible_, distorted_visible_;
  // Radii scattered to the model's rows (distorted renders).
  DeviceBuffer<float> radii_;
  // Ground truth, render and dLoss/d(render) of the rendered region (HWC);
  // Render's image.
  DeviceBuffer<float> truth_, image_, grad_image_, check_image_;
  // The last Forward's pass (alive until BackwardAndUpdate).
  std::unique_ptr<RenderContext> context_;
  std::unique_ptr<CudaDensityControl> density_;
};

}  // namespace watergs
