// HiDDeN training steps on the GPU (see cuda_decoder_training.h), following
// TrainStep in decoder_training.cc line by line.
#include "watermark/cuda/cuda_decoder_training.h"

#include <algorithm>
#include <cmath>

#include "gaussian/util/error.h"

namespace watergs {

StepResult CudaTrainStep(CudaHiddenModel& model, CudaNetworkAdam& adam,
                         ImageNoise& noise, NoiseKind kind,
                         const DeviceTensor& cover,
                         const std::vector<float>& targets, float image_weight,
                         std::mt19937* rng, CudaStepBuffers* buf) {
  if (!model.encoder) Fail("CudaTrainStep: the model has no encoder");
  std::vector<float> signs(targets.size());
  for (size_t i = 0; i < targets.size(); ++i) signs[i] = 2.f * targets[i] - 1.f;
  buf->targets.Upload(targets);
  buf->signs.Upload(signs);
  adam.ZeroGrad();
  const DeviceTensor& watermarked =
      model.encoder->Forward(cover, buf->signs, true);
  cover.Download(&buf->host_cover);
  watermarked.Download(&buf->host_watermarked);
  // Identity: the decoder reads the watermarked batch itself (the CPU's
  // identity layer copies it and draws nothing from rng). Other layers run
  // on the host.
  const bool host_noise = kind != NoiseKind::kIdentity;
  if (host_noise) {
    noise.Forward(kind, buf->host_watermarked, buf->host_cover,
                  &buf->host_noised, rng);
    buf->noised.Upload(buf->host_noised);
  }
  const DeviceTensor& logits =
      model.decoder->Forward(host_noise ? buf->noised : watermarked, true);
  StepResult result;
  result.bce = CudaBceWithLogits(logits, buf->targets, &buf->dlogits);
  logits.Download(&buf->host_logits);
  result.accuracy = BitAccuracy(buf->host_logits, targets);
  result.psnr = BatchPsnr(buf->host_cover, buf->host_watermarked);
  model.decoder->Backward(
      buf->dlogits, host_noise ? &buf->dnoised : &buf->dimage, true, true);
  if (host_noise) {
    buf->dnoised.Download(&buf->host_dnoised);
    noise.Backward(buf->host_dnoised, &buf->host_dimage);
    buf->dimage.Upload(buf->host_dimage);
  }
  CudaAddMseGradient(watermarked, cover, image_weight, &buf->dimage);
  model.encoder->Backward(buf->dimage, true);
  adam.Step();
  return result;
}

CudaDecoderTrainer::CudaDecoderTrainer(HiddenModel& model,
                                       const NetworkAdam& adam, bool allow_tf32)
    : context_(std::make_unique<CudaNnContext>(allow_tf32)),
      model_(std::make_unique<CudaHiddenModel>(context_.get(), model)) {
  if (!model_->encoder) Fail("CudaDecoderTrainer: the model has no encoder");
  adam_ = std::make_unique<CudaNetworkAdam>(model_->AllParameters(),
                                            adam.learning_rate);
  adam_->CopyFrom(adam);
}

StepResult CudaDecoderTrainer::Step(ImageNoise& noise, NoiseKind kind,
                                    const Tensor& cover,
                                    const std::vector<float>& targets,
                                    float image_weight, std::mt19937* rng) {
  cover_.Upload(cover);
  return CudaTrainStep(*model_, *adam_, noise, kind, cover_, targets,
                       image_weight, rng, &buffers_);
}

void CudaDecoderTrainer::CopyToHost(HiddenModel* model, NetworkAdam* adam) {
  model_->CopyToHost(model);
  adam_->CopyToHost(adam);
}

}  // namespace watergs
