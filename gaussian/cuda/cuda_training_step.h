// The device-resident training step of Trainer (trainer.h) when its
// rasterizer is a CudaRasterizer: model, Adam moments, gradients, rendered
// and gradient images stay on the GPU. Per iteration only the ground-truth
// image goes up and, while density control accumulates statistics, the
// visibility bytes, NDC gradient norms and (when asked) screen radii come
// down (5-9 bytes per Gaussian instead of ~0.5 KB each way). The trainer's
// host model and Adam are a mirror: pulled from the device before anything
// reads them (Pull*), pushed back after the host edits them (MarkHost*);
// device_training_step.h has the contract. With density control taken over
// (CudaDensityControl, cuda_density.h) nothing per Gaussian comes down at
// all, not even at densifications and resets. Host C++ (C++20); only the
// .cu files it calls must stay C++17.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/camera.h"
#include "gaussian/cuda/compact_gradient_buffers.h"
#include "gaussian/cuda/cuda_adam.h"
#include "gaussian/cuda/cuda_density.h"
#include "gaussian/cuda/cuda_loss.h"
#include "gaussian/cuda/cuda_model_mirror.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/device_training_step.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"

namespace watergs {

class CudaTrainingStep : public DeviceTrainingStep {
 public:
  // `rasterizer`, `host_model` and `host_adam` (the trainer's) must outlive
  // this. Float32 moments only (CudaAdam refuses the others). The device
  // copies are built from the host ones at the first Forward.
  CudaTrainingStep(CudaRasterizer* rasterizer, const AdamOptions& adam_options,
                   double scene_extent, double lambda_dssim,
                   GaussianModel* host_model, Adam* host_adam);
  ~CudaTrainingStep() override;

  // DeviceTrainingStep. The truth image is uploaded; the radii come from
  // the CUDA projection. The Adam state mirrored is the moments, step
  // counts, enabled groups and rejected count; masks set on the host Adam
  // are not (the trainer sets none). With density control taken, Backward
  // keeps the view's context (its screen radii) until DensityStep.
  void Forward(const RenderCamera& camera, const RenderOptions& options,
               const ImageRGB& truth) override;
  LossTerms Loss() override;
  void Backward(GaussianGradients* statistics,
                std::vector<float>* radii) override;
  size_t AdamStep(int64_t iteration, bool skip_opacity) override;
  void Synchronize() override;
  void PullModel() override;
  void PullAdam() override;
  void MarkHostModelEdited() override;
  void MarkHostAdamEdited() override;
  void PushIfStale() override;
  size_t NumGaussians() const override;
  bool TakeDensityControl(const DensityOptions& options, double scene_extent,
                          const std::string& state) override;
  DensityEvent DensityStep(int64_t iteration) override;
  std::string SaveDensityState() const override;
  void LoadDensityState(const std::string& state) override;

 private:
  // Sizes the gradient buffers to the device model.
  CudaGradientArrays GradientArrays();

  CudaRasterizer* rasterizer_;
  // The device model and Adam, mirroring the trainer's host copies.
  CudaModelMirror mirror_;
  CudaTrainingLoss loss_;
  // Gradients (factored SH), densification norms and visibility, N rows.
  CompactGradientBuffers gradients_;
  // Ground truth, render and dLoss/d(render) of the current view (HWC).
  DeviceBuffer<float> truth_, image_, grad_image_;
  int width_ = 0, height_ = 0;
  // SH degree the current view was rendered with.
  int active_sh_degree_ = 0;
  // The current view's forward pass (alive from Forward to Backward).
  std::unique_ptr<RenderContext> context_;
  // Density control on the device (null until TakeDensityControl).
  std::unique_ptr<CudaDensityControl> density_;
};

}  // namespace watergs
