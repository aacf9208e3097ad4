// The training step Trainer (trainer.h) drives when the model, the Adam
// moments and the gradients live on an accelerator: the CUDA one
// (cuda/cuda_training_step.h) or a host emulation in tests, which checks
// the trainer's sync protocol without a GPU. The trainer's host model and
// Adam are the step's mirror: Pull* brings them up to date before the host
// reads them, MarkHost*Edited says the host changed them. A step may also
// own Inria's density control (TakeDensityControl), so that a densification
// or opacity reset needs no host round trip.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/camera.h"
#include "gaussian/density_strategy.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"

namespace watergs {

class DeviceTrainingStep {
 public:
  virtual ~DeviceTrainingStep() = default;
  // Renders the device model from `camera` and takes `truth` (HWC, the
  // render rect's size; Error otherwise). Pushes host edits first.
  virtual void Forward(const RenderCamera& camera, const RenderOptions& options,
                       const ImageRGB& truth) = 0;
  // Loss of the last Forward and its image gradient, kept on the device.
  virtual LossTerms Loss() = 0;
  // Backward of the last Forward into the device gradients. `statistics`
  // (nullable) receives visible and mean2d_grad_norm_ndc (N each), no other
  // array, and `radii` (nullable) ComputeScreenRadii's N screen radii.
  virtual void Backward(GaussianGradients* statistics,
                        std::vector<float>* radii) = 0;
  // Adam at 1-based `iteration` with the device gradients; the opacity group
  // is left alone when skip_opacity. Returns the rejected count.
  virtual size_t AdamStep(int64_t iteration, bool skip_opacity) = 0;
  // Waits for the device (stage timings).
  virtual void Synchronize() = 0;
  // Device -> host copies of the model and of the Adam state when the host
  // ones are behind.
  virtual void PullModel() = 0;
  virtual void PullAdam() = 0;
  // The host model / Adam were replaced or edited (after a Pull): the
  // device copies are rebuilt from them before the next use.
  virtual void MarkHostModelEdited() = 0;
  virtual void MarkHostAdamEdited() = 0;
  // Uploads the host copies the device is behind on.
  virtual void PushIfStale() = 0;
  // Gaussians in the model (the device copy or, when it is behind, the
  // host one).
  virtual size_t NumGaussians() const = 0;

  // Takes over density control: Inria's ADC with `options` over
  // `scene_extent`, continuing from `state` (DensityStrategy::SaveState of
  // the trainer's Inria strategy for the current model). Returns false when
  // the step has none: the trainer then keeps its host strategy.
  virtual bool TakeDensityControl(const DensityOptions& options,
                                  double scene_extent,
                                  const std::string& state) = 0;
  // Density control after Backward of 1-based `iteration` (only after
  // TakeDensityControl): statistics, clone / split / prune and opacity
  // reset on the device model and Adam, as the CPU strategy's PostBackward.
  virtual DensityEvent DensityStep(int64_t iteration) = 0;
  // The density state as the CPU strategy's SaveState writes it, and back
  // (for the current model; Error if the bytes do not fit).
  virtual std::string SaveDensityState() const = 0;
  virtual void LoadDensityState(const std::string& state) = 0;
};

// Makes a device step mirroring `host_model` and `host_adam` (the trainer's).
using DeviceTrainingStepFactory =
    std::function<std::unique_ptr<DeviceTrainingStep>(GaussianModel* host_model,
                                                      Adam* host_adam)>;

}  // namespace watergs
