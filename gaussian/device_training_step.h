// The training step Trainer (trainer.h) drives when the model, the Adam
// moments and the gradients live on an accelerator: the CUDA one
// (cuda/cuda_training_step.h) or a host emulation in tests, which checks
// the trainer's sync protocol without a GPU. The trainer's host model and
// Adam are the step's mirror: Pull* brings them up to date before the host
// reads them, MarkHost*Edited says the host changed them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/camera.h"
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
};

// Makes a device step mirroring `host_model` and `host_adam` (the trainer's).
using DeviceTrainingStepFactory =
    std::function<std::unique_ptr<DeviceTrainingStep>(GaussianModel* host_model,
                                                      Adam* host_adam)>;

}  // namespace watergs
