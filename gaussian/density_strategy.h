// Adaptive density control as a strategy object, separate from the model and
// the trainer: the trainer hands it each view's gradients after the backward
// pass and it may clone, split, prune or reset Gaussians, keeping the Adam
// moments in step. The default is Inria's 3DGS schedule (ADC).
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

struct DensityOptions {
  // Densify and prune every `densification_interval` iterations in
  // (densify_from_iter, densify_until_iter).
  int64_t densify_from_iter = 500;
  int64_t densify_until_iter = 15000;
  int64_t densification_interval = 100;
  // Opacities are reset to at most reset_opacity every this many iterations
  // (while densifying).
  int64_t opacity_reset_interval = 3000;
  double reset_opacity = 0.01;
  // Mean view-space gradient norm (Inria's NDC units, see
  // GaussianGradients::mean2d_grad_norm_ndc) that triggers densification.
  double grad_threshold = 2e-4;
  // Clone when the largest scale <= percent_dense * extent, else split.
  double percent_dense = 0.01;
  // Split into this many samples with scale / (0.8 * split_samples).
  int split_samples = 2;
  // Prune below this opacity, above this screen radius in pixels (only after
  // the first opacity reset; 0 disables) or above this fraction of the
  // extent in world scale (also only after the first reset).
  double min_opacity = 0.005;
  double max_screen_size = 20;
  double max_world_size = 0.1;
  // Inria also resets opacity at densify_from_iter with a white background.
  bool white_background = false;
  // Seeds the sampling of split positions.
  uint64_t seed = 0;
};

// What Inria's adaptive density control does after the backward pass of
// 1-based `iteration` (shared by the CPU strategy and the CUDA one, so the
// two schedules cannot drift apart; zero intervals disable their step).
struct InriaDensitySchedule {
  InriaDensitySchedule(const DensityOptions& options, int64_t iteration);
  // Statistics accumulate (iteration < densify_until_iter).
  bool accumulates = false;
  // Clone / split / prune, with the screen and world size limits once the
  // first opacity reset is past.
  bool densifies = false, size_limits = false;
  // Opacities reset to reset_opacity.
  bool resets_opacity = false;
  // Screen radii are read (max_screen_size pruning can use them).
  bool wants_radii = false;
  // The model or Adam state may change.
  bool MayChangeModel() const { return densifies || resets_opacity; }
};

// What one PostBackward call did.
struct DensityEvent {
  // Gaussians were added or removed (the model and Adam changed size).
  bool densified = false;
  // Opacities were reset (and the opacity moments zeroed).
  bool opacity_reset = false;
  // Counts of this event.
  size_t cloned = 0, split = 0, pruned = 0;
  // When densified: for each Gaussian now, its index before the event (its
  // source for clones and split samples).
  std::vector<int64_t> parent;
};

class DensityStrategy {
 public:
  virtual ~DensityStrategy() = default;
  // Sizes the statistics for `model` (all zero).
  virtual void Init(const GaussianModel& model) = 0;
  // Whether PostBackward at `iteration` uses per-Gaussian screen radii.
  virtual bool WantsRadii(int64_t iteration) const = 0;
  // Whether PostBackward at `iteration` reads `grads`. The GPU trainer
  // (cuda/cuda_training_step.h) downloads grads.visible and
  // grads.mean2d_grad_norm_ndc only then, and no other gradient array ever:
  // a strategy for that path must need no more. Conservative default.
  virtual bool ReadsGradients(int64_t iteration) const {
    (void)iteration;
    return true;
  }
  // Whether PostBackward at `iteration` may change the model or the Adam
  // state. The GPU trainer copies both to the host and back only then;
  // otherwise PostBackward sees a host model of the right size whose values
  // may be stale. Conservative default: every iteration.
  virtual bool MayChangeModel(int64_t iteration) const {
    (void)iteration;
    return true;
  }
  // After the backward pass of 1-based `iteration`: `grads` of this view,
  // `radii` (N screen radii in pixels, 0 if not visible) or null. May change
  // `model` and `adam` together; the trainer then skips that optimiser step
  // for changed groups (as Inria's replaced tensors have no gradient).
  virtual DensityEvent PostBackward(int64_t iteration,
                                    const GaussianGradients& grads,
                                    const std::vector<float>* radii,
                                    GaussianModel* model, Adam* adam) = 0;
  // The state a checkpoint must keep (statistics, RNG), as bytes.
  virtual std::string SaveState() const = 0;
  // Restores SaveState's bytes; throws Error if they do not fit.
  virtual void LoadState(const std::string& bytes) = 0;
  // Bytes of per-Gaussian statistics.
  virtual size_t BytesPerGaussian() const = 0;
};

// Inria's adaptive density control with `options`; `scene_extent` is Inria's
// cameras_extent.
std::unique_ptr<DensityStrategy> MakeInriaDensityStrategy(
    const DensityOptions& options, double scene_extent);

// The bytes of Inria's density state in a checkpoint (statistics per
// Gaussian and the split-sample RNG), shared by the CPU strategy and the CUDA
// density control so that checkpoints resume on either device.
std::string EncodeInriaDensityState(const std::vector<float>& grad_accum,
                                    const std::vector<uint16_t>& denom,
                                    const std::vector<float>& max_radii,
                                    const std::mt19937_64& rng);
// Inverse of EncodeInriaDensityState; throws Error for corrupt, truncated
// or inconsistent bytes (counts are checked before anything is allocated).
void DecodeInriaDensityState(const std::string& bytes,
                             std::vector<float>* grad_accum,
                             std::vector<uint16_t>* denom,
                             std::vector<float>* max_radii,
                             std::mt19937_64* rng);

// A strategy that never changes the model (fine-tuning without ADC).
std::unique_ptr<DensityStrategy> MakeFixedDensityStrategy();

// Per Gaussian: the opacity logit Inria's reset_opacity leaves,
// inverse_sigmoid(min(sigmoid(logit), max_opacity)).
float ResetOpacityLogit(float logit, double max_opacity);

}  // namespace watergs
