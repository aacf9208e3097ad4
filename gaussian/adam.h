// Adam over the parameter groups of a GaussianModel, with Inria's 3DGS
// learning rates and schedule. Moments live per group and follow the
// Gaussians when density control adds or removes them. Groups (or single
// Gaussians of a group) can be frozen: their parameters and moments are then
// left untouched bit for bit (watermark fine-tuning relies on this).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

constexpr int kNumParamGroups = 6;

// Inria's get_expon_lr_func: log-linear interpolation from lr_init (step 0)
// to lr_final (step >= max_steps), times an optional delay factor
// delay_mult + (1 - delay_mult) sin(pi/2 clamp(step / delay_steps, 0, 1)).
// Returns 0 for step < 0 or when both rates are 0.
double ExponentialLr(int64_t step, double lr_init, double lr_final,
                     int64_t delay_steps, double delay_mult, int64_t max_steps);

struct AdamOptions {
  // Position rates, multiplied by the scene extent (Inria's spatial_lr_scale).
  double position_lr_init = 1.6e-4;
  double position_lr_final = 1.6e-6;
  // Inria's position_lr_delay_mult; has no effect while delay_steps is 0.
  double position_lr_delay_mult = 0.01;
  int64_t position_lr_delay_steps = 0;
  // Iteration at which the position rate reaches its final value (Inria
  // fixes 30000; the trainer sets the run's length).
  int64_t position_lr_max_steps = 30000;
  // Constant rates of the other groups.
  double feature_lr = 2.5e-3;
  double feature_rest_lr = 2.5e-3 / 20.0;
  double opacity_lr = 0.05;
  double scaling_lr = 5e-3;
  double rotation_lr = 1e-3;
  // Adam constants (Inria: torch defaults with eps 1e-15).
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-15;
  // Compact moments (83 instead of 472 bytes per Gaussian at SH degree 3):
  // one second moment per Gaussian and group (the mean of g^2 over the
  // group's values, as Adam-mini does per block) and the first moment per
  // value as an 8-bit float relative to its square root. Not Inria's exact
  // optimiser; off by default.
  bool compact_moments = false;
  // Moments of every group but the positions stored as bfloat16 with
  // stochastic rounding (2 instead of 4 bytes per value; positions, whose
  // updates are the smallest relative to their values, keep float).
  bool half_moments = false;
};

// Multiplies every rate of `options` (positions, features, opacity, scales,
// rotations) by `scale`.
void ScaleRates(double scale, AdamOptions* options);

// Each group's learning rate at 1-based `iteration` (indexed by ParamGroup):
// Inria's exponentially decaying position rate times the scene extent, the
// other groups constant. Shared by the CPU and CUDA optimisers.
std::array<double, kNumParamGroups> GroupLearningRates(
    const AdamOptions& options, double scene_extent, int64_t iteration);

// Moments of one group and the update count used for bias correction
// (shared by the group, as in torch). Full moments: exp_avg and exp_avg_sq,
// N x stride floats each. Compact moments: exp_avg_q (N x stride 8-bit
// codes of exp_avg / sqrt(exp_avg_sq_shared)) and exp_avg_sq_shared (N).
struct AdamGroupState {
  std::vector<float> exp_avg;
  std::vector<float> exp_avg_sq;
  std::vector<uint8_t> exp_avg_q;
  std::vector<float> exp_avg_sq_shared;
  // Half moments: exp_avg and exp_avg_sq as bfloat16 bits.
  std::vector<uint16_t> exp_avg_h, exp_avg_sq_h;
  int64_t step = 0;
};

// The 8-bit float of compact moments: sign, 4-bit exponent (2^-8 .. 2^7),
// 3-bit mantissa, round to nearest (relative error <= 1/16), saturating;
// magnitudes below ~2^-8 become 0 (code 0).
uint8_t EncodeMomentCode(float x);
float DecodeMomentCode(uint8_t code);

// The model array and the gradient array of a group, and its floats per
// Gaussian.
std::vector<float>& GroupParams(GaussianModel& model, ParamGroup group);
const std::vector<float>& GroupParams(const GaussianModel& model,
                                      ParamGroup group);
const std::vector<float>& GroupGrads(const GaussianGradients& grads,
                                     ParamGroup group);
int GroupStride(const GaussianModel& model, ParamGroup group);
const char* GroupName(ParamGroup group);

class Adam {
 public:
  Adam(const AdamOptions& options, double scene_extent);

  // Sizes the moments to `model` with zeros and resets the step counts.
  void Init(const GaussianModel& model);
  // Sets the rates for 1-based `iteration` (Inria's update_learning_rate).
  void SetIteration(int64_t iteration);
  double LearningRate(ParamGroup group) const;
  void SetLearningRate(ParamGroup group, double lr);

  // A disabled group is never updated and its step count does not advance.
  void SetGroupEnabled(ParamGroup group, bool enabled);
  bool GroupEnabled(ParamGroup group) const;
  // Per-Gaussian mask of a group (N entries, nonzero = trainable); empty
  // means all. Gaussians appended later are trainable.
  void SetGaussianMask(ParamGroup group, std::vector<uint8_t> mask);

  // One Adam update of every enabled group. Non-finite gradient values are
  // treated as 0 (counted, never reach a parameter); an update that would
  // make a parameter non-finite is skipped and counted. Returns the count.
  size_t Step(const GaussianGradients& grads, GaussianModel* model);

  // Density-control bookkeeping: keep the Gaussians with keep[i] true (in
  // order); append `count` Gaussians with zero moments; zero a group's moments
  // (Inria does this for opacity at each opacity reset).
  void Filter(const std::vector<bool>& keep);
  void Append(size_t count);
  void ResetMoments(ParamGroup group);

  // Number of Gaussians the moments describe.
  size_t size() const { return num_gaussians_; }
  AdamGroupState& state(ParamGroup group) { return groups_[Index(group)]; }
  const AdamGroupState& state(ParamGroup group) const {
    return groups_[Index(group)];
  }
  // Non-finite values rejected by Step since Init.
  int64_t rejected_total() const { return rejected_total_; }
  void set_rejected_total(int64_t n) { rejected_total_ = n; }
  // Bytes of optimiser state per Gaussian (moments and masks).
  size_t BytesPerGaussian() const;
  const AdamOptions& options() const { return options_; }

 private:
  static int Index(ParamGroup group) { return static_cast<int>(group); }
  // Per-step scalars of one group's update, in float as torch computes them.
  struct StepConstants {
    float step_size, bias2_sqrt, w1, beta2, w2, eps;
  };
  // Advances the group's step count and returns its update scalars.
  StepConstants NextStepConstants(ParamGroup group,
                                  AdamGroupState* state) const;
  // Whether `group` keeps bfloat16 moments (AdamOptions::half_moments).
  bool UsesHalfMoments(ParamGroup group) const;
  size_t StepGroup(ParamGroup group, const GaussianGradients& grads, int stride,
                   std::vector<float>* params);
  size_t StepGroupCompact(ParamGroup group, const std::vector<float>& grad,
                          int stride, std::vector<float>* params);

  AdamOptions options_;
  double scene_extent_;
  size_t num_gaussians_ = 0;
  std::array<int, kNumParamGroups> strides_{};
  std::array<AdamGroupState, kNumParamGroups> groups_;
  std::array<double, kNumParamGroups> lr_{};
  std::array<bool, kNumParamGroups> enabled_{};
  std::array<std::vector<uint8_t>, kNumParamGroups> masks_;
  int64_t rejected_total_ = 0;
};

}  // namespace watergs
