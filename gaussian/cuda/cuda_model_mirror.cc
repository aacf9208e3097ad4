// The device model and its host mirror (see cuda_model_mirror.h).
#include "gaussian/cuda/cuda_model_mirror.h"

#include <string>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr ParamGroup kGroups[kNumParamGroups] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

void CheckModelArrays(const GaussianModel& model) {
  const size_t n = model.size();
  const size_t stride = static_cast<size_t>(model.sh_rest_stride());
  if (model.means.size() != 3 * n || model.log_scales.size() != 3 * n ||
      model.quats.size() != 4 * n || model.sh_dc.size() != 3 * n ||
      model.sh_rest.size() != n * stride) {
    Fail("GPU model: arrays do not all hold " + std::to_string(n) +
         " Gaussians of SH degree " + std::to_string(model.sh_degree));
  }
}

void FailCountMismatch(size_t adam, size_t model) {
  Fail("GPU model: optimiser state for " + std::to_string(adam) +
       " Gaussians, model has " + std::to_string(model));
}

}  // namespace

void DeviceGaussianArrays::Resize(size_t n) {
  means.Resize(n * 3);
  log_scales.Resize(n * 3);
  quats.Resize(n * 4);
  opacity_logits.Resize(n);
  sh_dc.Resize(n * 3);
  sh_rest.Resize(n * sh_rest_stride());
}

void DeviceGaussianArrays::Upload(const GaussianModel& model) {
  CheckModelArrays(model);
  sh_degree = model.sh_degree;
  means.Upload(model.means);
  log_scales.Upload(model.log_scales);
  quats.Upload(model.quats);
  opacity_logits.Upload(model.opacity_logits);
  sh_dc.Upload(model.sh_dc);
  sh_rest.Upload(model.sh_rest);
}

void DeviceGaussianArrays::Download(GaussianModel* model) const {
  model->sh_degree = sh_degree;
  means.Download(&model->means);
  log_scales.Download(&model->log_scales);
  quats.Download(&model->quats);
  opacity_logits.Download(&model->opacity_logits);
  sh_dc.Download(&model->sh_dc);
  sh_rest.Download(&model->sh_rest);
}

CudaModelArrays DeviceGaussianArrays::Arrays() const {
  CudaModelArrays m;
  m.means = means.data();
  m.log_scales = log_scales.data();
  m.quats = quats.data();
  m.opacity_logits = opacity_logits.data();
  m.sh_dc = sh_dc.data();
  m.sh_rest = sh_rest.data();
  m.sh_degree = sh_degree;
  m.count = size();
  return m;
}

CudaDensityModel DeviceGaussianArrays::DensityModel() {
  CudaDensityModel m;
  m.means = &means;
  m.log_scales = &log_scales;
  m.quats = &quats;
  m.opacity_logits = &opacity_logits;
  m.sh_dc = &sh_dc;
  m.sh_rest = &sh_rest;
  m.sh_degree = sh_degree;
  return m;
}

CudaModelMirror::CudaModelMirror(const AdamOptions& adam_options,
                                 double scene_extent, GaussianModel* host_model,
                                 Adam* host_adam)
    : adam_(adam_options, scene_extent),
      host_model_(host_model),
      host_adam_(host_adam),
      placeholder_(1) {
  placeholder_.Zero();
}

void CudaModelMirror::PullModel() {
  if (!host_model_stale_) return;
  model_.Download(host_model_);
  host_model_stale_ = false;
}

void CudaModelMirror::PullAdam() {
  if (!host_adam_stale_) return;
  // The host Adam takes the device's Gaussian count (density control may
  // have changed it) from the host model: sized by Init, then filled.
  PullModel();
  host_adam_->Init(*host_model_);
  for (ParamGroup group : kGroups) {
    host_adam_->state(group) = adam_.DownloadState(group);
  }
  host_adam_->set_rejected_total(rejected_base_ + adam_.rejected_total());
  host_adam_stale_ = false;
}

void CudaModelMirror::MarkHostModelEdited() {
  host_model_stale_ = false;
  device_model_stale_ = true;
}

void CudaModelMirror::MarkHostAdamEdited() {
  host_adam_stale_ = false;
  device_adam_stale_ = true;
}

void CudaModelMirror::PushIfStale() {
  if (device_model_stale_) {
    model_.Upload(*host_model_);
    device_model_stale_ = false;
  }
  const size_t count = model_.size();
  if (device_adam_stale_) {
    const Adam& a = *host_adam_;
    if (a.size() != count) FailCountMismatch(a.size(), count);
    // Init zeroes and sizes the moments; UploadState fills them.
    adam_.Init(count, model_.sh_degree);
    for (ParamGroup group : kGroups) {
      adam_.UploadState(group, a.state(group));
      adam_.SetGroupEnabled(group, a.GroupEnabled(group));
    }
    rejected_base_ = a.rejected_total();
    device_adam_stale_ = false;
  }
  // A host edit that resized the model without its optimiser state.
  if (adam_.size() != count) FailCountMismatch(adam_.size(), count);
}

size_t CudaModelMirror::NumGaussians() const {
  return device_model_stale_ ? host_model_->size() : model_.size();
}

CudaAdamArrays CudaModelMirror::AdamParams() {
  auto or_placeholder = [this](DeviceBuffer<float>& b) {
    return b.size() > 0 ? b.data() : placeholder_.data();
  };
  CudaAdamArrays a;
  auto index = [](ParamGroup g) { return static_cast<int>(g); };
  a.params[index(ParamGroup::kXyz)] = or_placeholder(model_.means);
  a.params[index(ParamGroup::kFDc)] = or_placeholder(model_.sh_dc);
  a.params[index(ParamGroup::kFRest)] = or_placeholder(model_.sh_rest);
  a.params[index(ParamGroup::kOpacity)] = or_placeholder(model_.opacity_logits);
  a.params[index(ParamGroup::kScaling)] = or_placeholder(model_.log_scales);
  a.params[index(ParamGroup::kRotation)] = or_placeholder(model_.quats);
  return a;
}

}  // namespace watergs
