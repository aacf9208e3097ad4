// CudaDensityControl: the host side of the CUDA density control. It follows
// InriaDensityStrategy (gaussian/density_strategy.cc) step by step; each
// per-Gaussian loop there is one kernel of density.cu here.
#include "gaussian/cuda/cuda_density.h"

#include <algorithm>
#include <cmath>

#include "gaussian/cuda/adam_kernels.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/cuda_device.h"
#include "gaussian/cuda/density_kernels.h"
#include "gaussian/density_strategy.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Rows of each model buffer, checked against the Gaussian count n.
struct GroupRef {
  DeviceBuffer<float>* buffer;
  int stride;
};

std::vector<GroupRef> Groups(const CudaDensityModel& model) {
  if (!model.means || !model.log_scales || !model.quats ||
      !model.opacity_logits || !model.sh_dc || !model.sh_rest) {
    Fail("CudaDensityControl: a model buffer is missing");
  }
  if (model.sh_degree < 0 || model.sh_degree > 3) {
    Fail("CudaDensityControl: SH degree " + std::to_string(model.sh_degree) +
         " is not 0-3");
  }
  return {{model.means, 3},
          {model.log_scales, 3},
          {model.quats, 4},
          {model.opacity_logits, 1},
          {model.sh_dc, 3},
          {model.sh_rest, 3 * (NumShCoeffs(model.sh_degree) - 1)}};
}

// Number of Gaussians of `model`; throws Error if the buffers disagree.
size_t ModelCount(const CudaDensityModel& model) {
  const size_t n = Groups(model)[0].buffer->size() / 3;
  for (const GroupRef& group : Groups(model)) {
    if (group.buffer->size() != n * group.stride) {
      Fail("CudaDensityControl: a model buffer has " +
           std::to_string(group.buffer->size()) + " floats, expected " +
           std::to_string(n * group.stride) + " for " + std::to_string(n) +
           " Gaussians");
    }
  }
  return n;
}

// model <- its rows index[0], index[1], ... (count rows).
void GatherModel(const CudaDensityModel& model, const int64_t* index,
                 size_t count) {
  for (const GroupRef& group : Groups(model)) {
    DeviceBuffer<float> out(count * group.stride);
    WATERGS_CUDA_CHECK(cuda_adam::LaunchGatherRows(
        group.buffer->data(), index, count, group.stride, out.data(), nullptr));
    *group.buffer = std::move(out);
  }
}

}  // namespace

CudaDensityControl::CudaDensityControl(const DensityOptions& options,
                                       double scene_extent)
    : options_(options), extent_(scene_extent), rng_(options.seed) {
  std::string why;
  if (!CudaDeviceVisible(&why)) Fail("CudaDensityControl: " + why);
  count_.Resize(1);
}

CudaDensityControl::~CudaDensityControl() { cudaFree(cub_scratch_); }

void CudaDensityControl::Init(size_t n) { ResetStats(n); }

bool CudaDensityControl::WantsRadii(int64_t iteration) const {
  return InriaDensitySchedule(options_, iteration).wants_radii;
}

bool CudaDensityControl::ReadsGradients(int64_t iteration) const {
  return InriaDensitySchedule(options_, iteration).accumulates;
}

bool CudaDensityControl::MayChangeModel(int64_t iteration) const {
  return InriaDensitySchedule(options_, iteration).MayChangeModel();
}

DensityEvent CudaDensityControl::PostBackward(int64_t iteration,
                                              const CudaGradientArrays& grads,
                                              const float* radii,
                                              const CudaDensityModel& model,
                                              CudaAdam* adam) {
  DensityEvent event;
  const InriaDensitySchedule schedule(options_, iteration);
  if (!schedule.accumulates) return event;
  const size_t n = ModelCount(model);
  if (grad_accum_.size() != n) ResetStats(n);
  if (n > 0 && (!grads.visible || !grads.mean2d_grad_norm_ndc)) {
    Fail("CudaDensityControl: the visibility and NDC gradient norms are null");
  }
  WATERGS_CUDA_CHECK(cuda_density::LaunchAccumulate(
      grads.visible, grads.mean2d_grad_norm_ndc, radii, n, grad_accum_.data(),
      denom_.data(), max_radii_.data()));
  if (schedule.densifies) {
    DensifyAndPrune(schedule.size_limits, model, adam, &event);
  }
  if (schedule.resets_opacity) {
    ResetOpacity(model, adam);
    event.opacity_reset = true;
  }
  return event;
}

size_t CudaDensityControl::Select(const DeviceBuffer<uint8_t>& flags, size_t n,
                                  DeviceBuffer<int64_t>* out) {
  iota_.Resize(n);
  out->Resize(n);
  WATERGS_CUDA_CHECK(cuda_density::SelectFlagged(
      flags.data(), n, iota_.data(), out->data(), count_.data(), &cub_scratch_,
      &cub_scratch_bytes_));
  int64_t count = 0;
  WATERGS_CUDA_CHECK(
      cudaMemcpy(&count, count_.data(), sizeof(count), cudaMemcpyDeviceToHost));
  out->Resize(static_cast<size_t>(count));
  return static_cast<size_t>(count);
}

void CudaDensityControl::DensifyAndPrune(bool size_limits,
                                         const CudaDensityModel& model,
                                         CudaAdam* adam, DensityEvent* event) {
  const size_t n = ModelCount(model);
  if (adam && adam->size() != n) {
    Fail("CudaDensityControl: optimiser state for " +
         std::to_string(adam->size()) + " Gaussians, model has " +
         std::to_string(n));
  }
  keep_.Resize(n);
  clone_.Resize(n);
  split_.Resize(n);
  WATERGS_CUDA_CHECK(cuda_density::LaunchClassify(
      grad_accum_.data(), denom_.data(), model.log_scales->data(), n,
      static_cast<float>(options_.grad_threshold),
      static_cast<float>(options_.percent_dense * extent_), keep_.data(),
      clone_.data(), split_.data()));
  // Order after densification, as the CPU strategy builds it: kept
  // originals, clones, then sample k of every split Gaussian, k = 0, 1, ...
  DeviceBuffer<int64_t> kept_index, clone_index, split_index;
  const size_t kept = Select(keep_, n, &kept_index);
  const size_t clones = Select(clone_, n, &clone_index);
  const size_t splits = Select(split_, n, &split_index);
  const size_t samples =
      static_cast<size_t>(std::max(0, options_.split_samples));
  const size_t m = kept + clones + samples * splits;
  DeviceBuffer<int64_t> parent(m);
  auto append = [&](const DeviceBuffer<int64_t>& from, size_t at) {
    if (from.size() == 0) return;
    WATERGS_CUDA_CHECK(cudaMemcpy(parent.data() + at, from.data(), from.bytes(),
                                  cudaMemcpyDeviceToDevice));
  };
  append(kept_index, 0);
  append(clone_index, kept);
  for (size_t k = 0; k < samples; ++k) {
    append(split_index, kept + clones + k * splits);
  }
  DeviceBuffer<float> radii;
  if (size_limits) {
    radii.Resize(m);
    WATERGS_CUDA_CHECK(cuda_density::LaunchGatherRadii(
        max_radii_.data(), parent.data(), kept, m, radii.data()));
  }
  GatherModel(model, parent.data(), m);
  SampleSplits(kept + clones, m - kept - clones, model);

  // Prune the densified set.
  keep_.Resize(m);
  const cuda_density::PruneRule rule{static_cast<float>(options_.min_opacity),
                                     size_limits, options_.max_screen_size,
                                     options_.max_world_size * extent_};
  WATERGS_CUDA_CHECK(cuda_density::LaunchPruneFlags(
      model.opacity_logits->data(), model.log_scales->data(), radii.data(), m,
      rule, keep_.data()));
  const size_t survivors = Select(keep_, m, &selected_);
  const size_t pruned = m - survivors;
  parent_.Resize(survivors);
  DeviceBuffer<int64_t> adam_index(survivors);
  WATERGS_CUDA_CHECK(cuda_density::LaunchComposeIndex(
      pruned > 0 ? selected_.data() : nullptr, parent.data(), kept, survivors,
      parent_.data(), adam_index.data()));
  if (pruned > 0) GatherModel(model, selected_.data(), survivors);
  if (adam) adam->GatherDevice(adam_index.data(), survivors);
  event->densified = true;
  event->cloned = clones;
  event->split = splits;
  event->pruned = pruned;
  ResetStats(survivors);
}

void CudaDensityControl::SampleSplits(size_t first, size_t count,
                                      const CudaDensityModel& model) {
  const float log_shrink =
      std::log(0.8f * static_cast<float>(options_.split_samples));
  // The CPU strategy's draws: a fresh distribution per densification, three
  // values per sample in row order.
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> normals(3 * count);
  for (double& z : normals) z = normal(rng_);
  if (count == 0) return;
  DeviceBuffer<double> device_normals;
  device_normals.Upload(normals);
  WATERGS_CUDA_CHECK(cuda_density::LaunchApplySplits(
      device_normals.data(), first, count, log_shrink, model.means->data(),
      model.log_scales->data(), model.quats->data()));
}

void CudaDensityControl::ResetOpacity(const CudaDensityModel& model,
                                      CudaAdam* adam) {
  const double max_opacity = options_.reset_opacity;
  // ResetOpacityLogit's replacement value, computed once as it computes it.
  const float reset_logit =
      static_cast<float>(std::log(max_opacity / (1.0 - max_opacity)));
  WATERGS_CUDA_CHECK(cuda_density::LaunchResetOpacity(
      model.opacity_logits->data(), model.opacity_logits->size(), max_opacity,
      reset_logit));
  if (adam) adam->ResetMoments(ParamGroup::kOpacity);
}

void CudaDensityControl::ResetStats(size_t n) {
  grad_accum_.Resize(n);
  denom_.Resize(n);
  max_radii_.Resize(n);
  grad_accum_.Zero();
  denom_.Zero();
  max_radii_.Zero();
}

void CudaDensityControl::DownloadParent(std::vector<int64_t>* parent) const {
  parent_.Download(parent);
}

void CudaDensityControl::DownloadStatistics(
    std::vector<float>* grad_accum, std::vector<uint16_t>* denom,
    std::vector<float>* max_radii) const {
  grad_accum_.Download(grad_accum);
  denom_.Download(denom);
  max_radii_.Download(max_radii);
}

std::string CudaDensityControl::SaveState() const {
  std::vector<float> grad_accum, max_radii;
  std::vector<uint16_t> denom;
  DownloadStatistics(&grad_accum, &denom, &max_radii);
  return EncodeInriaDensityState(grad_accum, denom, max_radii, rng_);
}

void CudaDensityControl::LoadState(const std::string& bytes) {
  std::vector<float> grad_accum, max_radii;
  std::vector<uint16_t> denom;
  std::mt19937_64 rng;
  DecodeInriaDensityState(bytes, &grad_accum, &denom, &max_radii, &rng);
  grad_accum_.Upload(grad_accum);
  denom_.Upload(denom);
  max_radii_.Upload(max_radii);
  rng_ = rng;
}

size_t CudaDensityControl::BytesPerGaussian() const {
  return sizeof(float) + sizeof(uint16_t) + sizeof(float);
}

}  // namespace watergs
