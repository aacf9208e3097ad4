// A GaussianModel and its Adam state resident on a CUDA device, mirroring
// host copies owned by a trainer or an embedder: a device step reads and
// updates the device copies; the host copies are refreshed only when
// something on the host reads them (Pull*) and are uploaded again only after
// the host edited them (MarkHost*Edited, then PushIfStale). Shared by the
// device-resident training step (cuda_training_step.h) and embedding step
// (watermark/cuda/cuda_embedding_step.h).
#pragma once

#include <cstddef>
#include <cstdint>

#include "gaussian/adam.h"
#include "gaussian/cuda/cuda_adam.h"
#include "gaussian/cuda/cuda_density.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

// A GaussianModel's arrays on the device, same layouts.
struct DeviceGaussianArrays {
  // Highest SH degree stored (0-3); sets the width of sh_rest.
  int sh_degree = 3;
  // N x 3, N x 3, N x 4, N, N x 3, N x sh_rest_stride() floats.
  DeviceBuffer<float> means, log_scales, quats, opacity_logits, sh_dc, sh_rest;

  // Number of Gaussians.
  size_t size() const { return opacity_logits.size(); }
  int sh_rest_stride() const { return 3 * (NumShCoeffs(sh_degree) - 1); }
  // Every array sized to n Gaussians (contents undefined).
  void Resize(size_t n);
  // Throws Error unless every array of `model` holds its Gaussian count.
  void Upload(const GaussianModel& model);
  void Download(GaussianModel* model) const;
  // The arrays as the rasterizer and density control read them.
  CudaModelArrays Arrays() const;
  CudaDensityModel DensityModel();
};

class CudaModelMirror {
 public:
  // `host_model` and `host_adam` must outlive this. Float32 moments only
  // (CudaAdam refuses the others). Nothing is uploaded before PushIfStale.
  CudaModelMirror(const AdamOptions& adam_options, double scene_extent,
                  GaussianModel* host_model, Adam* host_adam);

  // Device -> host copies of the model / the Adam state (moments, step
  // counts, rejected count; the host Adam is re-sized to the device's
  // Gaussians, its masks cleared) when the host ones are behind.
  void PullModel();
  void PullAdam();
  // The host model / Adam were replaced or edited (after a Pull): the device
  // copies are rebuilt from them at the next PushIfStale.
  void MarkHostModelEdited();
  void MarkHostAdamEdited();
  // Uploads what the device is behind on (Error if the host model and Adam
  // disagree on the Gaussian count). Enabled groups come along with the
  // moments; per-Gaussian masks set on the host Adam do not.
  void PushIfStale();
  // A device step changed the model and the moments: the host is behind.
  void MarkDeviceChanged() { host_model_stale_ = host_adam_stale_ = true; }
  // Gaussians in the model (the device copy or, when behind, the host one).
  size_t NumGaussians() const;

  // The device copies (valid after PushIfStale).
  DeviceGaussianArrays& model() { return model_; }
  const DeviceGaussianArrays& model() const { return model_; }
  CudaAdam& adam() { return adam_; }
  // Adam's parameter pointers for one step (a group with no values, sh_rest
  // at degree 0, gets a placeholder CudaAdam never reads).
  CudaAdamArrays AdamParams();

 private:
  CudaAdam adam_;
  GaussianModel* host_model_;
  Adam* host_adam_;
  DeviceGaussianArrays model_;
  // Which copy is behind: the host after a device step, the device after a
  // host edit (never both for one part).
  bool host_model_stale_ = false, host_adam_stale_ = false;
  bool device_model_stale_ = true, device_adam_stale_ = true;
  // The host Adam's rejected count when the device Adam was last rebuilt
  // (CudaAdam counts from its Init).
  int64_t rejected_base_ = 0;
  // One float for AdamParams' empty groups.
  DeviceBuffer<float> placeholder_;
};

}  // namespace watergs
