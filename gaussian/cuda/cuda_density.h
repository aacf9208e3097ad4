// Inria's adaptive density control (gaussian/density_strategy.h's
// MakeInriaDensityStrategy) on device arrays: the statistics accumulate on
// the GPU each iteration from the device gradients and screen radii, and
// clone / split / prune / opacity reset run there at the same iterations,
// with the same thresholds and the same order (clone, split, then prune the
// densified set) as the CPU strategy, so a GPU trainer never copies
// per-Gaussian data to the host for density control. The Adam moments
// follow through CudaAdam::GatherDevice (fresh zero moments for clones and
// split samples), as the CPU strategy's Filter/Append do to the CPU Adam.
//
// Split samples: for parity with the CPU strategy, the standard-normal
// offsets are drawn on the host from the same std::mt19937_64 stream, in the
// same order (3 per sample; sample k of every split Gaussian, k = 0, 1, ...)
// for just the split Gaussians (their count comes down as one number), then
// uploaded and applied on the device. SaveState/LoadState write the CPU
// strategy's bytes, so checkpoints stay interchangeable.
#pragma once

#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "gaussian/cuda/cuda_adam.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/density_strategy.h"

namespace watergs {

// The device model density control edits, GaussianModel layout; the buffers
// are replaced (resized) when Gaussians are added or removed.
struct CudaDensityModel {
  // N x 3, N x 3, N x 4, N, N x 3, N x sh_rest stride (may be empty at SH
  // degree 0).
  DeviceBuffer<float>*means = nullptr, *log_scales = nullptr, *quats = nullptr,
  *opacity_logits = nullptr, *sh_dc = nullptr, *sh_rest = nullptr;
  // Highest SH degree stored (0-3): fixes the sh_rest stride.
  int sh_degree = 0;
};

class CudaDensityControl {
 public:
  // Throws Error when no CUDA device is usable.
  CudaDensityControl(const DensityOptions& options, double scene_extent);
  ~CudaDensityControl();
  CudaDensityControl(const CudaDensityControl&) = delete;
  CudaDensityControl& operator=(const CudaDensityControl&) = delete;

  // Sizes the statistics for n Gaussians (all zero).
  void Init(size_t n);
  // As the CPU strategy's WantsRadii, ReadsGradients and MayChangeModel.
  bool WantsRadii(int64_t iteration) const;
  bool ReadsGradients(int64_t iteration) const;
  bool MayChangeModel(int64_t iteration) const;

  // After the backward pass of 1-based `iteration`: grads.visible and
  // grads.mean2d_grad_norm_ndc (device, N each) of this view; `radii`
  // (device, N screen radii in pixels) or null when !WantsRadii. May resize
  // and edit `model` and `adam` (null: no optimiser state follows). The
  // event's parent list is left empty (DownloadParent has it).
  DensityEvent PostBackward(int64_t iteration, const CudaGradientArrays& grads,
                            const float* radii, const CudaDensityModel& model,
                            CudaAdam* adam);
  // For each Gaussian after the last densification, its index before it.
  void DownloadParent(std::vector<int64_t>* parent) const;
  // The statistics, as the CPU strategy keeps them (tests, checkpoints).
  void DownloadStatistics(std::vector<float>* grad_accum,
                          std::vector<uint16_t>* denom,
                          std::vector<float>* max_radii) const;

  // The CPU strategy's checkpoint bytes (statistics and RNG) and back;
  // LoadState throws Error if they do not fit.
  std::string SaveState() const;
  void LoadState(const std::string& bytes);
  // Number of Gaussians the statistics describe.
  size_t size() const { return grad_accum_.size(); }
  // Bytes of per-Gaussian statistics (as the CPU strategy's).
  size_t BytesPerGaussian() const;

 private:
  void ResetStats(size_t n);
  // Clone, split and prune; fills the event.
  void DensifyAndPrune(bool size_limits, const CudaDensityModel& model,
                       CudaAdam* adam, DensityEvent* event);
  // Indices i < n with flags[i] != 0 into out (resized); returns the count.
  size_t Select(const DeviceBuffer<uint8_t>& flags, size_t n,
                DeviceBuffer<int64_t>* out);
  // Draws and applies the split samples of rows first .. first + count.
  void SampleSplits(size_t first, size_t count, const CudaDensityModel& model);
  void ResetOpacity(const CudaDensityModel& model, CudaAdam* adam);

  DensityOptions options_;
  double extent_;
  std::mt19937_64 rng_;
  // Per Gaussian: sum of NDC gradient norms, views it was visible in, and
  // its largest screen radius since the last densification.
  DeviceBuffer<float> grad_accum_;
  DeviceBuffer<uint16_t> denom_;
  DeviceBuffer<float> max_radii_;
  // Last densification's parent list.
  DeviceBuffer<int64_t> parent_;
  // Scratch: flags, index lists, CUB temp storage, selected count.
  DeviceBuffer<uint8_t> keep_, clone_, split_;
  DeviceBuffer<int64_t> iota_, selected_;
  DeviceBuffer<int64_t> count_;
  void* cub_scratch_ = nullptr;
  size_t cub_scratch_bytes_ = 0;
};

}  // namespace watergs
