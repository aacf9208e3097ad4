// Host side of the CUDA Adam (see cuda_adam.h); kernels in adam.cu.
#include "gaussian/cuda/cuda_adam.h"

#include <cmath>
#include <string>
#include <utility>

#include "gaussian/cuda/adam_kernels.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/cuda_device.h"
#include "gaussian/sh.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr ParamGroup kGroups[kNumParamGroups] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

bool IsShGroup(ParamGroup group) {
  return group == ParamGroup::kFDc || group == ParamGroup::kFRest;
}

cuda_adam::ShConstants ShBasisConstants() {
  cuda_adam::ShConstants c;
  c.c0 = kShC0;
  c.c1 = kShC1;
  for (int k = 0; k < 5; ++k) c.c2[k] = kShC2[k];
  for (int k = 0; k < 7; ++k) c.c3[k] = kShC3[k];
  return c;
}

}  // namespace

CudaAdam::CudaAdam(const AdamOptions& options, double scene_extent)
    : options_(options), scene_extent_(scene_extent) {
  if (options.compact_moments) {
    Fail(
        "CudaAdam: compact optimiser moments (--compact_optimizer) are "
        "CPU-only; use --device cpu or full moments");
  }
  if (options.half_moments) {
    Fail(
        "CudaAdam: bfloat16 optimiser moments (--moment_precision bf16) are "
        "CPU-only; use --device cpu or float32 moments");
  }
  std::string why;
  if (!CudaDeviceVisible(&why)) Fail("CudaAdam: " + why);
  enabled_.fill(true);
  SetIteration(0);
}

void CudaAdam::Init(const GaussianModel& model) {
  Init(model.size(), model.sh_degree);
}

void CudaAdam::Init(size_t n, int sh_degree) {
  if (sh_degree < 0 || sh_degree > 3) {
    Fail("CudaAdam: SH degree " + std::to_string(sh_degree) + " outside 0-3");
  }
  GaussianModel shape;  // only for GroupStride
  shape.sh_degree = sh_degree;
  num_gaussians_ = n;
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    strides_[g] = GroupStride(shape, group);
    exp_avg_[g].Resize(n * strides_[g]);
    exp_avg_[g].Zero();
    exp_avg_sq_[g].Resize(n * strides_[g]);
    exp_avg_sq_[g].Zero();
    steps_[g] = 0;
    masks_[g].clear();
    SyncMask(g);
  }
  rejected_total_ = 0;
}

void CudaAdam::SetIteration(int64_t iteration) {
  lr_ = GroupLearningRates(options_, scene_extent_, iteration);
}

void CudaAdam::SetGroupEnabled(ParamGroup group, bool enabled) {
  enabled_[Index(group)] = enabled;
}

void CudaAdam::SetGaussianMask(ParamGroup group, std::vector<uint8_t> mask) {
  if (!mask.empty() && mask.size() != num_gaussians_) {
    Fail("CudaAdam: mask for " + std::string(GroupName(group)) + " has " +
         std::to_string(mask.size()) + " entries, model has " +
         std::to_string(num_gaussians_));
  }
  masks_[Index(group)] = std::move(mask);
  SyncMask(Index(group));
}

void CudaAdam::SyncMask(int g) {
  if (masks_[g].empty()) {
    device_masks_[g] = DeviceBuffer<uint8_t>();
  } else {
    device_masks_[g].Upload(masks_[g]);
  }
}

size_t CudaAdam::Step(const GaussianGradients& grads, GaussianModel* model) {
  if (model->size() != num_gaussians_) {
    Fail("CudaAdam: model has " + std::to_string(model->size()) +
         " Gaussians, optimiser state " + std::to_string(num_gaussians_));
  }
  CudaAdamArrays arrays;
  arrays.compact_sh = grads.compact_sh;
  arrays.sh_active_degree = grads.sh_active_degree;
  bool factored_used = false;
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    if (!enabled_[g]) continue;
    const std::vector<float>& params = GroupParams(*model, group);
    const bool factored = IsShGroup(group) && grads.compact_sh;
    const std::vector<float>& grad =
        factored ? grads.sh_color_grad : GroupGrads(grads, group);
    const size_t expected = factored ? 3 * num_gaussians_ : params.size();
    if (grad.size() != expected ||
        (factored && grads.sh_view_dir.size() != expected) ||
        params.size() != num_gaussians_ * strides_[g]) {
      Fail(std::string("CudaAdam: gradient of ") + GroupName(group) + " has " +
           std::to_string(grad.size()) + " values, expected " +
           std::to_string(expected));
    }
    param_stage_[g].Upload(params);
    arrays.params[g] = param_stage_[g].data();
    if (factored) {
      factored_used = true;
    } else {
      grad_stage_[g].Upload(grad);
      arrays.grads[g] = grad_stage_[g].data();
    }
  }
  if (factored_used) {
    color_grad_stage_.Upload(grads.sh_color_grad);
    view_dir_stage_.Upload(grads.sh_view_dir);
    arrays.sh_color_grad = color_grad_stage_.data();
    arrays.sh_view_dir = view_dir_stage_.data();
  }
  const size_t rejected = StepDevice(arrays);
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    if (enabled_[g]) param_stage_[g].Download(&GroupParams(*model, group));
  }
  return rejected;
}

size_t CudaAdam::StepDevice(const CudaAdamArrays& arrays) {
  if (arrays.compact_sh &&
      (arrays.sh_active_degree < 0 || arrays.sh_active_degree > 3)) {
    Fail("CudaAdam: SH degree " + std::to_string(arrays.sh_active_degree) +
         " outside 0-3");
  }
  rejected_.Resize(1);
  rejected_.Zero();
  const cuda_adam::ShConstants sh = ShBasisConstants();
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    if (!enabled_[g]) continue;
    const bool factored = IsShGroup(group) && arrays.compact_sh;
    const bool missing = factored
                             ? (!arrays.sh_color_grad || !arrays.sh_view_dir)
                             : !arrays.grads[g];
    if (num_gaussians_ > 0 && (!arrays.params[g] || missing)) {
      Fail(std::string("CudaAdam: no device array for ") + GroupName(group));
    }
    // Adam::NextStepConstants: torch's scalars, rounded to float.
    const int64_t step = ++steps_[g];
    const double bias1 = 1.0 - std::pow(options_.beta1, double(step));
    const double bias2 = 1.0 - std::pow(options_.beta2, double(step));
    const cuda_adam::AdamConstants k{static_cast<float>(lr_[g] / bias1),
                                     static_cast<float>(std::sqrt(bias2)),
                                     static_cast<float>(1.0 - options_.beta1),
                                     static_cast<float>(options_.beta2),
                                     static_cast<float>(1.0 - options_.beta2),
                                     static_cast<float>(options_.eps)};
    const uint8_t* mask =
        device_masks_[g].size() > 0 ? device_masks_[g].data() : nullptr;
    if (factored) {
      WATERGS_CUDA_CHECK(cuda_adam::LaunchAdamFactoredSh(
          k, sh, arrays.sh_color_grad, arrays.sh_view_dir,
          arrays.sh_active_degree, group == ParamGroup::kFDc,
          exp_avg_[g].data(), exp_avg_sq_[g].data(), arrays.params[g],
          num_gaussians_, strides_[g], mask, rejected_.data(), nullptr));
    } else {
      WATERGS_CUDA_CHECK(cuda_adam::LaunchAdamDense(
          k, arrays.grads[g], exp_avg_[g].data(), exp_avg_sq_[g].data(),
          arrays.params[g], num_gaussians_, strides_[g], mask, rejected_.data(),
          nullptr));
    }
  }
  unsigned long long rejected = 0;
  WATERGS_CUDA_CHECK(cudaMemcpy(&rejected, rejected_.data(), sizeof(rejected),
                                cudaMemcpyDeviceToHost));
  rejected_total_ += static_cast<int64_t>(rejected);
  return static_cast<size_t>(rejected);
}

void CudaAdam::Gather(const std::vector<int64_t>& index) {
  for (size_t i = 0; i < index.size(); ++i) {
    if (index[i] >= static_cast<int64_t>(num_gaussians_)) {
      Fail("CudaAdam::Gather: index " + std::to_string(index[i]) + " at " +
           std::to_string(i) + " is past the " +
           std::to_string(num_gaussians_) + " Gaussians");
    }
  }
  index_stage_.Upload(index);
  GatherDevice(index_stage_.data(), index.size());
}

void CudaAdam::GatherDevice(const int64_t* index, size_t count) {
  bool any_mask = false;
  for (const auto& mask : masks_) any_mask = any_mask || !mask.empty();
  if (any_mask) {  // masks live on the host: they need the index there
    std::vector<int64_t> host(count);
    if (count > 0) {
      WATERGS_CUDA_CHECK(cudaMemcpy(host.data(), index, count * sizeof(int64_t),
                                    cudaMemcpyDeviceToHost));
    }
    for (size_t i = 0; i < count; ++i) {
      if (host[i] >= static_cast<int64_t>(num_gaussians_)) {
        Fail("CudaAdam::GatherDevice: index " + std::to_string(host[i]) +
             " at " + std::to_string(i) + " is past the " +
             std::to_string(num_gaussians_) + " Gaussians");
      }
    }
    for (int g = 0; g < kNumParamGroups; ++g) {
      if (masks_[g].empty()) continue;
      std::vector<uint8_t> gathered(count);
      for (size_t i = 0; i < count; ++i) {
        gathered[i] = host[i] < 0 ? 1 : masks_[g][host[i]];
      }
      masks_[g] = std::move(gathered);
      SyncMask(g);
    }
  }
  for (int g = 0; g < kNumParamGroups; ++g) {
    for (auto* moments : {&exp_avg_[g], &exp_avg_sq_[g]}) {
      DeviceBuffer<float> gathered(count * strides_[g]);
      WATERGS_CUDA_CHECK(cuda_adam::LaunchGatherRows(moments->data(), index,
                                                     count, strides_[g],
                                                     gathered.data(), nullptr));
      *moments = std::move(gathered);
    }
  }
  num_gaussians_ = count;
}

void CudaAdam::Filter(const std::vector<bool>& keep) {
  if (keep.size() != num_gaussians_) {
    Fail("CudaAdam::Filter: keep has " + std::to_string(keep.size()) +
         " entries, optimiser state " + std::to_string(num_gaussians_));
  }
  std::vector<int64_t> index;
  for (size_t i = 0; i < keep.size(); ++i) {
    if (keep[i]) index.push_back(static_cast<int64_t>(i));
  }
  Gather(index);
}

void CudaAdam::Append(size_t count) {
  std::vector<int64_t> index(num_gaussians_ + count, -1);
  for (size_t i = 0; i < num_gaussians_; ++i) {
    index[i] = static_cast<int64_t>(i);
  }
  Gather(index);
}

void CudaAdam::ResetMoments(ParamGroup group) {
  exp_avg_[Index(group)].Zero();
  exp_avg_sq_[Index(group)].Zero();
}

AdamGroupState CudaAdam::DownloadState(ParamGroup group) const {
  AdamGroupState state;
  exp_avg_[Index(group)].Download(&state.exp_avg);
  exp_avg_sq_[Index(group)].Download(&state.exp_avg_sq);
  state.step = steps_[Index(group)];
  return state;
}

void CudaAdam::UploadState(ParamGroup group, const AdamGroupState& state) {
  const int g = Index(group);
  const size_t n = num_gaussians_ * strides_[g];
  if (state.exp_avg.size() != n || state.exp_avg_sq.size() != n) {
    Fail(std::string("CudaAdam: moments of ") + GroupName(group) + " have " +
         std::to_string(state.exp_avg.size()) + " and " +
         std::to_string(state.exp_avg_sq.size()) + " values, expected " +
         std::to_string(n) + " (float32 moments only)");
  }
  exp_avg_[g].Upload(state.exp_avg);
  exp_avg_sq_[g].Upload(state.exp_avg_sq);
  steps_[g] = state.step;
}

size_t CudaAdam::BytesPerGaussian() const {
  size_t bytes = 0;
  for (int g = 0; g < kNumParamGroups; ++g) {
    bytes += 2 * sizeof(float) * strides_[g];
    if (!masks_[g].empty()) bytes += 1;
  }
  return bytes;
}

}  // namespace watergs
