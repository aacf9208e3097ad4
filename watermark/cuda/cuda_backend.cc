// The CUDA backend's answers to watermark/backend.h.
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "watermark/backend.h"
#include "watermark/cuda/cuda_decoder_training.h"
#include "watermark/cuda/cuda_embedding_step.h"
#include "watermark/cuda/cuda_feature_decoder.h"
#include "watermark/cuda/cuda_hidden.h"
#include "watermark/cuda/device_patch_decoder.h"

namespace watergs {
namespace {

// CudaDecoderTrainer behind the backend-neutral interface.
class CudaDecoderTrainerStep : public DeviceDecoderTrainer {
 public:
  CudaDecoderTrainerStep(HiddenModel& model, const NetworkAdam& adam,
                         bool allow_tf32)
      : trainer_(model, adam, allow_tf32) {}
  StepResult Step(ImageNoise& noise, NoiseKind kind, const Tensor& cover,
                  const std::vector<float>& targets, float image_weight,
                  std::mt19937* rng) override {
    return trainer_.Step(noise, kind, cover, targets, image_weight, rng);
  }
  void CopyToHost(HiddenModel* model, NetworkAdam* adam) override {
    trainer_.CopyToHost(model, adam);
  }

 private:
  CudaDecoderTrainer trainer_;
};

// The option that keeps an embedding step on the host although the
// rasterizer and decoder run on the GPU; empty when none does.
std::string HostStepReason(const EmbedOptions& options) {
  if (options.adam.compact_moments || options.adam.half_moments) {
    return "8-bit or bfloat16 moments have no CUDA Adam";
  }
  if (options.decoder_jitter.enabled())
    return "decoder jitter runs on the host";
  if (options.jpeg_quality > 0 && options.jpeg_fraction > 0) {
    return "the JPEG layer runs on the host";
  }
  if (options.masking > 0) return "texture masking runs on the host";
  return "";
}

}  // namespace

std::unique_ptr<BitDecoder> LoadGpuBitDecoder(const std::string& path,
                                              int expected_bits, bool feature) {
  // No TF32: the GPU decoder then reads what the CPU one does (parity tests).
  if (feature) return CudaFeatureDecoder::Load(path, expected_bits, false);
  return std::make_unique<CudaDecoder>(
      CudaDecoder::Load(path, expected_bits, false));
}

std::unique_ptr<BitDecoder> MakeGpuHiddenDecoder(HiddenModel& model,
                                                 bool allow_tf32) {
  return std::make_unique<CudaDecoder>(model, allow_tf32);
}

std::unique_ptr<BitDecoder> MakeGpuFeatureDecoder(FeatureNet& net,
                                                  bool allow_tf32) {
  return std::make_unique<CudaFeatureDecoder>(net, allow_tf32);
}

std::unique_ptr<DeviceDecoderTrainer> MakeGpuDecoderTrainer(
    HiddenModel& model, const NetworkAdam& adam, bool allow_tf32) {
  return std::make_unique<CudaDecoderTrainerStep>(model, adam, allow_tf32);
}

DeviceEmbeddingStepFactory DeviceEmbeddingStepFor(
    Rasterizer& rasterizer, BitDecoder& decoder, const EmbedOptions& options,
    double scene_extent, const std::vector<float>& targets,
    std::string* host_step_reason) {
  // With a CUDA rasterizer and either CUDA decoder (HiDDeN or random
  // feature, reading the render in place) everything per Gaussian stays on
  // the GPU, unless an option has no device twin: then the host step runs
  // (renders and decoder still on the GPU).
  auto* cuda_rasterizer = dynamic_cast<CudaRasterizer*>(&rasterizer);
  auto* cuda_decoder = dynamic_cast<DevicePatchDecoder*>(&decoder);
  if (!cuda_rasterizer || !cuda_decoder) return nullptr;
  *host_step_reason = HostStepReason(options);
  if (!host_step_reason->empty()) return nullptr;
  return [=](GaussianModel* host_model, Adam* host_adam) {
    return std::make_unique<CudaEmbeddingStep>(
        cuda_rasterizer, cuda_decoder, options.adam, scene_extent, options.beta,
        options.gamma, options.margin, targets, host_model, host_adam,
        options.mse_weight);
  };
}

}  // namespace watergs
