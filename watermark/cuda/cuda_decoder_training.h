// HiDDeN encoder/decoder training steps on the GPU: the twin of TrainStep
// (decoder_training.h) and a trainer that keeps the networks and Adam state
// on the device between steps and copies them back for checkpoints and
// validation. The identity noise layer stays on the device; the others run
// on the CPU's ImageNoise (the watermarked batch goes down and the gradient
// back up), so every noise layer trains exactly as on the CPU. Parity:
// tests/watermark/cuda_decoder_test.cc.
#pragma once

#include <memory>
#include <random>
#include <vector>

#include "watermark/cuda/cuda_hidden.h"
#include "watermark/decoder_training.h"
#include "watermark/image_noise.h"

namespace watergs {

// Reusable buffers of CudaTrainStep.
struct CudaStepBuffers {
  // Message bits (0/1) and signs (+-1).
  DeviceBuffer<float> targets, signs;
  // Decoder input under a host noise layer, gradients of the logits, of the
  // decoder input and of the watermarked batch.
  DeviceTensor noised, dlogits, dnoised, dimage;
  // Host copies: logits, cover, watermarked, noised and gradients.
  Tensor host_logits, host_cover, host_watermarked, host_noised, host_dnoised,
      host_dimage;
};

// TrainStep on the device: cover [N,3,H,W] in [-1,1] (device), targets N*L
// bits (0/1), noise `kind` (drawn from rng as the CPU does), loss
// image_weight * MSE + BCE, backward through decoder, noise and encoder,
// one Adam update. The model needs its encoder.
StepResult CudaTrainStep(CudaHiddenModel& model, CudaNetworkAdam& adam,
                         ImageNoise& noise, NoiseKind kind,
                         const DeviceTensor& cover,
                         const std::vector<float>& targets, float image_weight,
                         std::mt19937* rng, CudaStepBuffers* buffers);

// Training state on the device for a TrainDecoder-style loop: built from the
// CPU model and optimiser (after a resume, say), stepped on the device, and
// copied back whenever the CPU side needs it (checkpoint, validation, end).
class CudaDecoderTrainer {
 public:
  // Copies the weights, running statistics and Adam state (same parameter
  // order: HiddenModel::AllParameters). allow_tf32: see CudaNnContext.
  CudaDecoderTrainer(HiddenModel& model, const NetworkAdam& adam,
                     bool allow_tf32 = false);
  // One step on a host batch (see CudaTrainStep).
  StepResult Step(ImageNoise& noise, NoiseKind kind, const Tensor& cover,
                  const std::vector<float>& targets, float image_weight,
                  std::mt19937* rng);
  // Device weights, statistics and Adam state into `model` and `adam` (the
  // ones the trainer was built from, or the same architecture).
  void CopyToHost(HiddenModel* model, NetworkAdam* adam);

 private:
  // The handles first: the layers point into them.
  std::unique_ptr<CudaNnContext> context_;
  std::unique_ptr<CudaHiddenModel> model_;
  std::unique_ptr<CudaNetworkAdam> adam_;
  // Uploaded batch and step buffers.
  DeviceTensor cover_;
  CudaStepBuffers buffers_;
};

}  // namespace watergs
