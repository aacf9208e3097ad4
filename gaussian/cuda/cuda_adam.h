// Adam on a CUDA device: the CPU Adam's update (gaussian/adam.h) with its
// per-group learning rates and schedule, bias correction, non-finite
// rejection, frozen groups, per-Gaussian masks and factored SH gradients,
// with the moments resident on the device. Full float32 moments only: the
// compact and bfloat16 moment layouts stay CPU-only and are refused.
// tests/gaussian/cuda_adam_test.cc checks parity with the CPU Adam.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// Device arrays of one Adam step, indexed by ParamGroup.
struct CudaAdamArrays {
  // Parameters of each group, N x stride floats (updated in place).
  std::array<float*, kNumParamGroups> params{};
  // Dense gradients of each group, N x stride floats; the f_dc and f_rest
  // entries are unused when compact_sh.
  std::array<const float*, kNumParamGroups> grads{};
  // Factored SH gradients (GaussianGradients::compact_sh): dL/dcolour and
  // the unnormalised view direction, N x 3 each, at sh_active_degree.
  bool compact_sh = false;
  const float* sh_color_grad = nullptr;
  const float* sh_view_dir = nullptr;
  int sh_active_degree = 0;
};

class CudaAdam {
 public:
  // Throws Error for compact or bfloat16 moments (CPU-only layouts) and when
  // no CUDA device is usable.
  CudaAdam(const AdamOptions& options, double scene_extent);

  // Sizes the moments to `model` (or to n Gaussians of SH degree sh_degree)
  // with zeros and resets the step counts, masks and rejection count.
  void Init(const GaussianModel& model);
  void Init(size_t n, int sh_degree);
  // Learning rates, as Adam's.
  void SetIteration(int64_t iteration);
  double LearningRate(ParamGroup group) const { return lr_[Index(group)]; }
  void SetLearningRate(ParamGroup group, double lr) { lr_[Index(group)] = lr; }
  // Frozen groups and per-Gaussian masks, as Adam's.
  void SetGroupEnabled(ParamGroup group, bool enabled);
  bool GroupEnabled(ParamGroup group) const { return enabled_[Index(group)]; }
  void SetGaussianMask(ParamGroup group, std::vector<uint8_t> mask);

  // Adam::Step on host arrays: uploads the parameters and gradients of the
  // enabled groups, updates them on the device and downloads the
  // parameters. Same checks and errors; returns the rejected count.
  size_t Step(const GaussianGradients& grads, GaussianModel* model);
  // The same update on device arrays (the parameters change in place).
  // Waits for the device to read the rejected count back.
  size_t StepDevice(const CudaAdamArrays& arrays);

  // Moments follow the Gaussians: Gaussian i afterwards has the moments of
  // Gaussian index[i] before, or zero moments where index[i] < 0 (clones
  // and split children, as Inria's densification does). Masks follow too
  // (new Gaussians trainable). GatherDevice takes a device index list,
  // every entry < size() (checked only when masks bring it to the host).
  void Gather(const std::vector<int64_t>& index);
  void GatherDevice(const int64_t* index, size_t count);
  // Adam's Filter, Append and ResetMoments, on the device.
  void Filter(const std::vector<bool>& keep);
  void Append(size_t count);
  void ResetMoments(ParamGroup group);

  // Number of Gaussians the moments describe.
  size_t size() const { return num_gaussians_; }
  // A group's moments and step count copied to the host (full layout:
  // exp_avg, exp_avg_sq, step), e.g. for a checkpoint or a parity test.
  AdamGroupState DownloadState(ParamGroup group) const;
  // Replaces a group's moments and step count (full layout, size() rows),
  // e.g. to resume from a CPU checkpoint.
  void UploadState(ParamGroup group, const AdamGroupState& state);
  // Non-finite values rejected since Init.
  int64_t rejected_total() const { return rejected_total_; }
  // Bytes of optimiser state per Gaussian (moments and masks).
  size_t BytesPerGaussian() const;
  const AdamOptions& options() const { return options_; }

 private:
  static int Index(ParamGroup group) { return static_cast<int>(group); }
  // Uploads the host mask of a group (or clears the device copy).
  void SyncMask(int g);

  AdamOptions options_;
  double scene_extent_;
  size_t num_gaussians_ = 0;
  std::array<int, kNumParamGroups> strides_{};
  std::array<int64_t, kNumParamGroups> steps_{};
  std::array<double, kNumParamGroups> lr_{};
  std::array<bool, kNumParamGroups> enabled_{};
  // Moments per group on the device.
  std::array<DeviceBuffer<float>, kNumParamGroups> exp_avg_, exp_avg_sq_;
  // Masks per group: the host copy (empty = all) and its device copy.
  std::array<std::vector<uint8_t>, kNumParamGroups> masks_;
  std::array<DeviceBuffer<uint8_t>, kNumParamGroups> device_masks_;
  int64_t rejected_total_ = 0;
  // Staging for Step's host arrays and Gather's index list.
  std::array<DeviceBuffer<float>, kNumParamGroups> param_stage_, grad_stage_;
  DeviceBuffer<float> color_grad_stage_, view_dir_stage_;
  DeviceBuffer<int64_t> index_stage_;
  DeviceBuffer<unsigned long long> rejected_;
};

}  // namespace watergs
