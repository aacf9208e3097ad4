// The device-resident training step (see cuda_training_step.h): device
// buffers, the host <-> device mirror, and one iteration's stages on the
// CUDA rasterizer, CudaTrainingLoss and CudaAdam.
#include "gaussian/cuda/cuda_training_step.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <string>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/error.h"

namespace watergs {
namespace {

constexpr ParamGroup kGroups[kNumParamGroups] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

int Index(ParamGroup group) { return static_cast<int>(group); }

// Throws Error unless every array of `model` holds its Gaussian count.
void CheckModelArrays(const GaussianModel& model) {
  const size_t n = model.size();
  const size_t stride = static_cast<size_t>(model.sh_rest_stride());
  if (model.means.size() != 3 * n || model.log_scales.size() != 3 * n ||
      model.quats.size() != 4 * n || model.sh_dc.size() != 3 * n ||
      model.sh_rest.size() != n * stride) {
    Fail("training on the GPU: model arrays do not all hold " +
         std::to_string(n) + " Gaussians of SH degree " +
         std::to_string(model.sh_degree));
  }
}

}  // namespace

CudaTrainingStep::CudaTrainingStep(CudaRasterizer* rasterizer,
                                   const AdamOptions& adam_options,
                                   double scene_extent, double lambda_dssim,
                                   GaussianModel* host_model, Adam* host_adam)
    : rasterizer_(rasterizer),
      adam_(adam_options, scene_extent),
      loss_(lambda_dssim),
      host_model_(host_model),
      host_adam_(host_adam),
      placeholder_(1) {
  placeholder_.Zero();
}

CudaTrainingStep::~CudaTrainingStep() = default;

void CudaTrainingStep::PullModel() {
  if (!host_model_stale_) return;
  GaussianModel& m = *host_model_;
  means_.Download(&m.means);
  log_scales_.Download(&m.log_scales);
  quats_.Download(&m.quats);
  opacity_logits_.Download(&m.opacity_logits);
  sh_dc_.Download(&m.sh_dc);
  sh_rest_.Download(&m.sh_rest);
  host_model_stale_ = false;
}

void CudaTrainingStep::PullAdam() {
  if (!host_adam_stale_) return;
  for (ParamGroup group : kGroups) {
    host_adam_->state(group) = adam_.DownloadState(group);
  }
  host_adam_->set_rejected_total(rejected_base_ + adam_.rejected_total());
  host_adam_stale_ = false;
}

void CudaTrainingStep::MarkHostModelEdited() {
  host_model_stale_ = false;
  device_model_stale_ = true;
}

void CudaTrainingStep::MarkHostAdamEdited() {
  host_adam_stale_ = false;
  device_adam_stale_ = true;
}

void CudaTrainingStep::PushIfStale() {
  if (device_model_stale_) {
    const GaussianModel& m = *host_model_;
    CheckModelArrays(m);
    means_.Upload(m.means);
    log_scales_.Upload(m.log_scales);
    quats_.Upload(m.quats);
    opacity_logits_.Upload(m.opacity_logits);
    sh_dc_.Upload(m.sh_dc);
    sh_rest_.Upload(m.sh_rest);
    sh_degree_ = m.sh_degree;
    count_ = m.size();
    device_model_stale_ = false;
  }
  if (device_adam_stale_) {
    const Adam& a = *host_adam_;
    if (a.size() != count_) {
      Fail("training on the GPU: optimiser state for " +
           std::to_string(a.size()) + " Gaussians, model has " +
           std::to_string(count_));
    }
    // Init zeroes and sizes the moments; UploadState fills them.
    adam_.Init(count_, sh_degree_);
    for (ParamGroup group : kGroups) {
      adam_.UploadState(group, a.state(group));
      adam_.SetGroupEnabled(group, a.GroupEnabled(group));
    }
    rejected_base_ = a.rejected_total();
    device_adam_stale_ = false;
  }
  // A host edit that resized the model without its optimiser state.
  if (adam_.size() != count_) {
    Fail("training on the GPU: optimiser state for " +
         std::to_string(adam_.size()) + " Gaussians, model has " +
         std::to_string(count_));
  }
}

CudaModelArrays CudaTrainingStep::ModelArrays() const {
  CudaModelArrays m;
  m.means = means_.data();
  m.log_scales = log_scales_.data();
  m.quats = quats_.data();
  m.opacity_logits = opacity_logits_.data();
  m.sh_dc = sh_dc_.data();
  m.sh_rest = sh_rest_.data();
  m.sh_degree = sh_degree_;
  m.count = count_;
  return m;
}

CudaGradientArrays CudaTrainingStep::GradientArrays() {
  const size_t n = count_;
  for (DeviceBuffer<float>* b :
       {&grad_means_, &grad_log_scales_, &grad_color_, &grad_view_dir_}) {
    b->Resize(3 * n);
  }
  grad_quats_.Resize(4 * n);
  for (DeviceBuffer<float>* b :
       {&grad_opacity_, &grad_norm_, &grad_norm_ndc_}) {
    b->Resize(n);
  }
  visible_.Resize(n);
  CudaGradientArrays g;
  g.means = grad_means_.data();
  g.log_scales = grad_log_scales_.data();
  g.quats = grad_quats_.data();
  g.opacity_logits = grad_opacity_.data();
  g.compact_sh = true;
  g.sh_color_grad = grad_color_.data();
  g.sh_view_dir = grad_view_dir_.data();
  g.mean2d_grad_norm = grad_norm_.data();
  g.mean2d_grad_norm_ndc = grad_norm_ndc_.data();
  g.visible = visible_.data();
  return g;
}

void CudaTrainingStep::Forward(const RenderCamera& camera,
                               const RenderOptions& options,
                               const ImageRGB& truth) {
  PushIfStale();
  const PixelRect rect = ResolveRenderRect(camera, options);
  const size_t values =
      3 * static_cast<size_t>(rect.width) * static_cast<size_t>(rect.height);
  // TrainingLoss::Evaluate's check and message.
  if (truth.width != rect.width || truth.height != rect.height ||
      truth.data.size() != values) {
    Fail("loss: image sizes differ (" + std::to_string(rect.width) + "x" +
         std::to_string(rect.height) + " vs " + std::to_string(truth.width) +
         "x" + std::to_string(truth.height) + ")");
  }
  truth_.Upload(truth.data);
  image_.Resize(values);
  grad_image_.Resize(values);
  width_ = rect.width, height_ = rect.height;
  active_sh_degree_ = options.active_sh_degree < 0
                          ? sh_degree_
                          : std::min(options.active_sh_degree, sh_degree_);
  context_.reset();
  rasterizer_->ForwardDevice(ModelArrays(), camera, options, image_.data(),
                             &context_);
}

LossTerms CudaTrainingStep::Loss() {
  return loss_.EvaluateDevice(image_.data(), truth_.data(), width_, height_,
                              grad_image_.data());
}

void CudaTrainingStep::Backward(GaussianGradients* statistics,
                                std::vector<float>* radii) {
  if (!context_) Fail("CudaTrainingStep: Backward without a Forward");
  rasterizer_->BackwardDevice(*context_, grad_image_.data(), GradientArrays());
  if (radii) rasterizer_->DownloadScreenRadii(*context_, radii);
  // DensityStep reads the radii from the context's workspace (which stays
  // allocated in the rasterizer's pool either way).
  if (!density_) context_.reset();
  if (statistics) {
    visible_.Download(&statistics->visible);
    grad_norm_ndc_.Download(&statistics->mean2d_grad_norm_ndc);
  }
}

size_t CudaTrainingStep::AdamStep(int64_t iteration, bool skip_opacity) {
  adam_.SetIteration(iteration);
  auto or_placeholder = [this](DeviceBuffer<float>& b) {
    return b.size() > 0 ? b.data() : placeholder_.data();
  };
  CudaAdamArrays a;
  a.params[Index(ParamGroup::kXyz)] = or_placeholder(means_);
  a.params[Index(ParamGroup::kFDc)] = or_placeholder(sh_dc_);
  a.params[Index(ParamGroup::kFRest)] = or_placeholder(sh_rest_);
  a.params[Index(ParamGroup::kOpacity)] = or_placeholder(opacity_logits_);
  a.params[Index(ParamGroup::kScaling)] = or_placeholder(log_scales_);
  a.params[Index(ParamGroup::kRotation)] = or_placeholder(quats_);
  a.grads[Index(ParamGroup::kXyz)] = grad_means_.data();
  a.grads[Index(ParamGroup::kOpacity)] = grad_opacity_.data();
  a.grads[Index(ParamGroup::kScaling)] = grad_log_scales_.data();
  a.grads[Index(ParamGroup::kRotation)] = grad_quats_.data();
  a.compact_sh = true;
  a.sh_color_grad = grad_color_.data();
  a.sh_view_dir = grad_view_dir_.data();
  a.sh_active_degree = active_sh_degree_;
  const bool opacity_enabled = adam_.GroupEnabled(ParamGroup::kOpacity);
  if (skip_opacity) adam_.SetGroupEnabled(ParamGroup::kOpacity, false);
  const size_t rejected = adam_.StepDevice(a);
  adam_.SetGroupEnabled(ParamGroup::kOpacity, opacity_enabled);
  host_model_stale_ = host_adam_stale_ = true;
  return rejected;
}

size_t CudaTrainingStep::NumGaussians() const {
  return device_model_stale_ ? host_model_->size() : count_;
}

bool CudaTrainingStep::TakeDensityControl(const DensityOptions& options,
                                          double scene_extent,
                                          const std::string& state) {
  density_ = std::make_unique<CudaDensityControl>(options, scene_extent);
  LoadDensityState(state);
  return true;
}

DensityEvent CudaTrainingStep::DensityStep(int64_t iteration) {
  if (!density_) Fail("CudaTrainingStep: DensityStep without density control");
  const float* radii = nullptr;
  if (density_->WantsRadii(iteration)) {
    if (!context_) Fail("CudaTrainingStep: DensityStep without a Backward");
    radii = rasterizer_->DeviceScreenRadii(*context_);
  }
  CudaDensityModel model;
  model.means = &means_;
  model.log_scales = &log_scales_;
  model.quats = &quats_;
  model.opacity_logits = &opacity_logits_;
  model.sh_dc = &sh_dc_;
  model.sh_rest = &sh_rest_;
  model.sh_degree = sh_degree_;
  const DensityEvent event =
      density_->PostBackward(iteration, GradientArrays(), radii, model, &adam_);
  context_.reset();
  if (event.densified || event.opacity_reset) {
    // GradientArrays resizes the gradients at the next Backward.
    count_ = means_.size() / 3;
    host_model_stale_ = host_adam_stale_ = true;
  }
  return event;
}

std::string CudaTrainingStep::SaveDensityState() const {
  if (!density_) Fail("CudaTrainingStep: no density control to save");
  return density_->SaveState();
}

void CudaTrainingStep::LoadDensityState(const std::string& state) {
  if (!density_) Fail("CudaTrainingStep: no density control to load");
  density_->Init(NumGaussians());
  density_->LoadState(state);
}

void CudaTrainingStep::Synchronize() {
  WATERGS_CUDA_CHECK(cudaDeviceSynchronize());
}

}  // namespace watergs
