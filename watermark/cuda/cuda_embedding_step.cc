// The device-resident embedding step (see cuda_embedding_step.h).
#include "watermark/cuda/cuda_embedding_step.h"

#include <cuda_runtime.h>

#include <chrono>
#include <string>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/util/error.h"
#include "watermark/embedder.h"

namespace watergs {
namespace {

using Clock = std::chrono::steady_clock;

// Waits for the device, then returns the seconds since `*since` and moves
// it to now (stage timings of asynchronous work).
double StageSeconds(Clock::time_point* since) {
  WATERGS_CUDA_CHECK(cudaDeviceSynchronize());
  const Clock::time_point now = Clock::now();
  const double s = std::chrono::duration<double>(now - *since).count();
  *since = now;
  return s;
}

// Rows of each of the eight float gradient arrays (CudaEmbeddingStep's
// grads_ order) for a model of rest stride `rest`.
int Stride(int array, int rest) {
  constexpr int kStrides[8] = {3, 3, 4, 1, 3, -1, 1, 1};
  return array == 5 ? rest : kStrides[array];
}

}  // namespace

CudaEmbeddingStep::CudaEmbeddingStep(
    CudaRasterizer* rasterizer, DevicePatchDecoder* decoder,
    const AdamOptions& adam_options, double scene_extent, double beta,
    double gamma, double margin, std::vector<float> targets,
    GaussianModel* host_model, Adam* host_adam, double mse_weight)
    : rasterizer_(rasterizer),
      decoder_(decoder),
      mirror_(adam_options, scene_extent, host_model, host_adam),
      loss_(beta),
      gamma_(gamma),
      margin_(margin),
      mse_weight_(mse_weight),
      targets_(std::move(targets)) {}

CudaEmbeddingStep::~CudaEmbeddingStep() = default;

void CudaEmbeddingStep::TakeDensityControl(const DensityOptions& options,
                                           double scene_extent,
                                           const std::string& state) {
  density_ = std::make_unique<CudaDensityControl>(options, scene_extent);
  LoadDensityState(state);
}

void CudaEmbeddingStep::MarkHostEdited() {
  mirror_.MarkHostModelEdited();
  mirror_.MarkHostAdamEdited();
}

std::string CudaEmbeddingStep::SaveDensityState() const {
  if (!density_) Fail("CudaEmbeddingStep: no density control to save");
  return density_->SaveState();
}

void CudaEmbeddingStep::LoadDensityState(const std::string& state) {
  if (!density_) Fail("CudaEmbeddingStep: no density control to load");
  density_->Init(NumGaussians());
  density_->LoadState(state);
}

CudaDistortionLayer& CudaEmbeddingStep::DeviceLayer(
    const DistortionLayer& layer) {
  std::unique_ptr<CudaDistortionLayer>& twin = layers_[ToString(layer.spec())];
  if (!twin) twin = std::make_unique<CudaDistortionLayer>(layer.spec());
  return *twin;
}

DeviceEmbedLoss CudaEmbeddingStep::Forward(const DeviceEmbedView& view,
                                           std::mt19937_64& rng) {
  mirror_.PushIfStale();
  DeviceEmbedLoss out;
  Clock::time_point t = Clock::now();
  distorted_this_step_ = view.layer && !view.layer->IsIdentity();
  if (distorted_this_step_) {
    DeviceLayer(*view.layer).Apply(mirror_.model(), rng, &distorted_, &source_);
  }
  out.distortion_s = StageSeconds(&t);

  const PixelRect rect = ResolveRenderRect(view.camera, view.options);
  const ImageRGB& truth = *view.truth;
  const size_t values = 3 * size_t(rect.width) * size_t(rect.height);
  CheckImageSize(rect.width, rect.height, truth);
  const PixelRect crop = view.decoder_crop.empty()
                             ? PixelRect{0, 0, rect.width, rect.height}
                             : view.decoder_crop;
  if (crop.y0 < 0 || crop.y0 + crop.height > rect.height) {
    Fail("embed: decoder crop outside the rendered region");
  }
  truth_.Upload(truth.data);
  image_.Resize(values);
  grad_image_.Resize(values);
  context_.reset();
  const DeviceGaussianArrays& rendered =
      distorted_this_step_ ? distorted_ : mirror_.model();
  rasterizer_->ForwardDevice(rendered.Arrays(), view.camera, view.options,
                             image_.data(), &context_);
  out.render_s = StageSeconds(&t);

  out.image =
      mse_weight_ > 0
          ? loss_.MseDevice(image_.data(), truth_.data(), values, mse_weight_,
                            grad_image_.data())
          : loss_.EvaluateDevice(image_.data(), truth_.data(), rect.width,
                                 rect.height, grad_image_.data());
  out.image_loss_s = StageSeconds(&t);

  const std::vector<float> logits =
      decoder_->LogitsDevicePatch(image_.data(), rect.width, crop);
  std::vector<float> dlogits;
  out.bce = MessageBce(logits, targets_, gamma_, &dlogits, &out.bit_errors,
                       margin_, view.reference_logits);
  decoder_->AddInputGradientDevicePatch(dlogits, grad_image_.data(), rect.width,
                                        crop);
  out.decoder_s = StageSeconds(&t);
  return out;
}

void CudaEmbeddingStep::Render(const RenderCamera& camera,
                               const RenderOptions& options, ImageRGB* image) {
  mirror_.PushIfStale();
  const PixelRect rect = ResolveRenderRect(camera, options);
  check_image_.Resize(3 * size_t(rect.width) * size_t(rect.height));
  std::unique_ptr<RenderContext> context;
  rasterizer_->ForwardDevice(mirror_.model().Arrays(), camera, options,
                             check_image_.data(), &context);
  image->width = rect.width;
  image->height = rect.height;
  check_image_.Download(&image->data);
}

CudaGradientArrays CudaEmbeddingStep::Gradients(
    size_t n, int rest_stride, DeviceBuffer<float> (&buffers)[8],
    DeviceBuffer<uint8_t>* visible) {
  for (int a = 0; a < 8; ++a) buffers[a].Resize(n * Stride(a, rest_stride));
  visible->Resize(n);
  CudaGradientArrays g;
  g.means = buffers[0].data();
  g.log_scales = buffers[1].data();
  g.quats = buffers[2].data();
  g.opacity_logits = buffers[3].data();
  g.sh_dc = buffers[4].data();
  g.sh_rest = buffers[5].data();
  g.mean2d_grad_norm = buffers[6].data();
  g.mean2d_grad_norm_ndc = buffers[7].data();
  g.visible = visible->data();
  return g;
}

void CudaEmbeddingStep::ScatterToModel(size_t n_distorted) {
  const int rest = mirror_.model().sh_rest_stride();
  for (int a = 0; a < 8; ++a) {
    grads_[a].Zero();
    CudaScatterRows(distorted_grads_[a].data(), source_, n_distorted,
                    Stride(a, rest), grads_[a].data());
  }
  visible_.Zero();
  CudaScatterFlags(distorted_visible_.data(), source_, n_distorted,
                   visible_.data());
}

DensityEvent CudaEmbeddingStep::BackwardAndUpdate(int64_t iteration,
                                                  double* backward_s,
                                                  double* density_s,
                                                  double* adam_s) {
  if (!context_) Fail("CudaEmbeddingStep: BackwardAndUpdate without Forward");
  Clock::time_point t = Clock::now();
  DeviceGaussianArrays& model = mirror_.model();
  const size_t n = model.size();
  const int rest = model.sh_rest_stride();
  CudaGradientArrays grads = Gradients(n, rest, grads_, &visible_);
  if (distorted_this_step_) {
    const size_t n_distorted = distorted_.size();
    rasterizer_->BackwardDevice(
        *context_, grad_image_.data(),
        Gradients(n_distorted, rest, distorted_grads_, &distorted_visible_));
    ScatterToModel(n_distorted);
  } else {
    rasterizer_->BackwardDevice(*context_, grad_image_.data(), grads);
  }
  *backward_s = StageSeconds(&t);

  DensityEvent event;
  if (density_) {
    const float* radii = nullptr;
    if (density_->WantsRadii(iteration)) {
      radii = rasterizer_->DeviceScreenRadii(*context_);
      if (distorted_this_step_) {
        radii_.Resize(n);
        radii_.Zero();
        CudaScatterRows(radii, source_, distorted_.size(), 1, radii_.data());
        radii = radii_.data();
      }
    }
    event = density_->PostBackward(iteration, grads, radii,
                                   model.DensityModel(), &mirror_.adam());
    if (event.densified) density_->DownloadParent(&event.parent);
    if (event.densified || event.opacity_reset) mirror_.MarkDeviceChanged();
  }
  context_.reset();
  *density_s = StageSeconds(&t);

  if (!event.densified) {
    CudaAdam& adam = mirror_.adam();
    adam.SetIteration(iteration);
    CudaAdamArrays a = mirror_.AdamParams();
    for (int g = 0; g < kNumParamGroups; ++g) {
      // ParamGroup order: xyz, f_dc, f_rest, opacity, scaling, rotation.
      constexpr int kArray[kNumParamGroups] = {0, 4, 5, 3, 1, 2};
      a.grads[g] =
          grads_[kArray[g]].size() > 0 ? grads_[kArray[g]].data() : a.params[g];
    }
    adam.StepDevice(a);
    mirror_.MarkDeviceChanged();
  }
  *adam_s = StageSeconds(&t);
  return event;
}

}  // namespace watergs
