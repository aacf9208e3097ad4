// The device-resident training step (see cuda_training_step.h): device
// buffers, the host <-> device mirror, and one iteration's stages on the
// CUDA rasterizer, CudaTrainingLoss and CudaAdam.
#include "gaussian/cuda/cuda_training_step.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <string>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/render_conventions.h"
#include "gaussian/util/error.h"

namespace watergs {
CudaTrainingStep::CudaTrainingStep(CudaRasterizer* rasterizer,
                                   const AdamOptions& adam_options,
                                   double scene_extent, double lambda_dssim,
                                   GaussianModel* host_model, Adam* host_adam)
    : rasterizer_(rasterizer),
      mirror_(adam_options, scene_extent, host_model, host_adam),
      loss_(lambda_dssim) {}

CudaTrainingStep::~CudaTrainingStep() = default;

void CudaTrainingStep::PullModel() { mirror_.PullModel(); }
void CudaTrainingStep::PullAdam() { mirror_.PullAdam(); }
void CudaTrainingStep::MarkHostModelEdited() { mirror_.MarkHostModelEdited(); }
void CudaTrainingStep::MarkHostAdamEdited() { mirror_.MarkHostAdamEdited(); }
void CudaTrainingStep::PushIfStale() { mirror_.PushIfStale(); }

CudaGradientArrays CudaTrainingStep::GradientArrays() {
  return gradients_.Resize(mirror_.model().size());
}

void CudaTrainingStep::Forward(const RenderCamera& camera,
                               const RenderOptions& options,
                               const ImageRGB& truth) {
  PushIfStale();
  RequireDefaultConventions(options.conventions, "the CUDA training step");
  const PixelRect rect = ResolveRenderRect(camera, options);
  const size_t values =
      3 * static_cast<size_t>(rect.width) * static_cast<size_t>(rect.height);
  CheckImageSize(rect.width, rect.height, truth);
  truth_.Upload(truth.data);
  image_.Resize(values);
  grad_image_.Resize(values);
  width_ = rect.width, height_ = rect.height;
  const int sh_degree = mirror_.model().sh_degree;
  active_sh_degree_ = options.active_sh_degree < 0
                          ? sh_degree
                          : std::min(options.active_sh_degree, sh_degree);
  context_.reset();
  rasterizer_->ForwardDevice(mirror_.model().Arrays(), camera, options,
                             image_.data(), &context_);
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
    gradients_.visible.Download(&statistics->visible);
    gradients_.norm_ndc.Download(&statistics->mean2d_grad_norm_ndc);
  }
}

size_t CudaTrainingStep::AdamStep(int64_t iteration, bool skip_opacity) {
  CudaAdam& adam = mirror_.adam();
  adam.SetIteration(iteration);
  CudaAdamArrays a = mirror_.AdamParams();
  a.grads[static_cast<int>(ParamGroup::kXyz)] = gradients_.means.data();
  a.grads[static_cast<int>(ParamGroup::kOpacity)] =
      gradients_.opacity_logits.data();
  a.grads[static_cast<int>(ParamGroup::kScaling)] =
      gradients_.log_scales.data();
  a.grads[static_cast<int>(ParamGroup::kRotation)] = gradients_.quats.data();
  a.compact_sh = true;
  a.sh_color_grad = gradients_.color.data();
  a.sh_view_dir = gradients_.view_dir.data();
  a.sh_active_degree = active_sh_degree_;
  const bool opacity_enabled = adam.GroupEnabled(ParamGroup::kOpacity);
  if (skip_opacity) adam.SetGroupEnabled(ParamGroup::kOpacity, false);
  const size_t rejected = adam.StepDevice(a);
  adam.SetGroupEnabled(ParamGroup::kOpacity, opacity_enabled);
  mirror_.MarkDeviceChanged();
  return rejected;
}

size_t CudaTrainingStep::NumGaussians() const { return mirror_.NumGaussians(); }

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
  const DensityEvent event =
      density_->PostBackward(iteration, GradientArrays(), radii,
                             mirror_.model().DensityModel(), &mirror_.adam());
  context_.reset();
  // GradientArrays resizes the gradients at the next Backward.
  if (event.densified || event.opacity_reset) mirror_.MarkDeviceChanged();
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
