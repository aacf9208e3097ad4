// End-to-end training of the HiDDeN encoder and decoder (paper, "Universal
// Watermark Decoder"): random crops of natural photos, random messages,
// loss image_weight * MSE(cover, watermarked) + BCE(message, logits), one 2D
// noise layer sampled per step, Adam, checkpoints, resume and per-epoch
// validation on held-out photos. The steps run on the CPU or, with the CUDA
// backend, on the GPU (cuda/cuda_decoder_training.h); checkpoints, weights
// and validation are the CPU's either way, so a run resumes on either device.
#pragma once

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "watermark/hidden_model.h"
#include "watermark/image_noise.h"

namespace watergs {

// Figures of one training step.
struct StepResult {
  // Mean BCE of the step, encoder PSNR (dB) and bit accuracy (0..1).
  double bce = 0, psnr = 0, accuracy = 0;
};

struct DecoderTrainingOptions {
  // Folder of training photos (jpg/png), searched recursively.
  std::string image_path;
  // Folder of held-out photos; empty: no validation.
  std::string validation_path;
  // Weights file (decoder + encoder); its checkpoint is output_path + ".ckpt".
  std::string output_path;
  HiddenConfig config;
  // Square training crop side in pixels.
  int crop = 128;
  // Center-crop side for validation (0: whole held-out photos).
  int validation_crop = 128;
  int epochs = 10;
  int batch_size = 8;
  // Optimiser steps per epoch; 0: one crop per training photo.
  int steps_per_epoch = 0;
  float learning_rate = 1e-3f;
  // Weight of MSE(cover, watermarked) on [-1,1] images.
  float image_weight = 0.7f;
  // > 0: image_weight is adapted (x1.02 per step when the running PSNR is
  // below, /1.02 above) to hold this encoder PSNR in dB.
  float target_psnr = 0.f;
  // The PSNR target ramps linearly from target_psnr_start to target_psnr
  // over the first psnr_ramp_steps steps: a loud watermark first lets the
  // decoder find the message, which is then made quieter.
  float target_psnr_start = 24.f;
  int psnr_ramp_steps = 0;
  // > 0: the PSNR target advances (by one ramp step) only on steps whose
  // running training bit accuracy is at least this (0..1), so the watermark
  // gets quieter only as fast as the decoder keeps reading it.
  float accuracy_gate = 0.f;
  // Noise layers sampled uniformly, one per step.
  std::vector<NoiseKind> noise = {NoiseKind::kIdentity};
  bool resume = false;
  // Checkpoint every this many steps (and at every epoch end).
  int checkpoint_every = 200;
  // Stops cleanly (checkpoint + weights) after this many minutes; 0: never.
  double max_minutes = 0;
  uint32_t seed = 1;
  // Where the steps run. kCuda needs the CUDA backend and a visible GPU
  // (TrainDecoder fails with one line saying which is missing).
  Device device = Device::kCpu;
  // kCuda only: cuDNN/cuBLAS may use TF32 tensor cores (faster, ~1e-3
  // relative error per layer instead of float32 rounding).
  bool allow_tf32 = false;
  // If set, called after every step with its 0-based index and figures
  // (tests compare the CPU and GPU trajectories through it).
  std::function<void(int64_t step, const StepResult& result)> on_step;
};

// Validation figures on held-out photos.
struct ValidationResult {
  // Mean encoder PSNR (dB, images in [0,1], watermarked clamped).
  double psnr = 0;
  // Bit accuracy per noise kind, in NoiseKind order (identity first).
  std::vector<std::pair<NoiseKind, double>> accuracy;
  int images = 0;
};

// The .jpg/.png photos in `dir` (recursive, sorted by path), each decoded by
// DecodeImageFile (float RGB in [0, 1], CV_32FC3, EXIF orientation ignored
// as every command reads images); Error naming the folder if it holds none,
// or the first file that is not a readable image. `paths` (if given) gets
// the photos' file paths, in the same order.
std::vector<cv::Mat> LoadPhotoFolder(const std::string& dir,
                                     std::vector<std::string>* paths = nullptr);

// Bit accuracy and PSNR of `model` on a center crop (side `crop`, the whole
// photo when 0) of each photo, one fixed-seed random message per photo, under
// no noise and each of the six noise layers.
ValidationResult Validate(HiddenModel& model,
                          const std::vector<cv::Mat>& photos, int crop,
                          uint32_t seed);
// One line per figure, e.g. "psnr 34.1 dB | identity 99.3% | crop 97.1% ...".
std::string FormatValidation(const ValidationResult& result);

// Fraction of logits [N,L] whose sign matches the target bit (0/1).
double BitAccuracy(const Tensor& logits, const std::vector<float>& targets);
// PSNR (dB) between two [-1,1] batches seen as [0,1] images, the second
// clamped to the valid range.
double BatchPsnr(const Tensor& cover, const Tensor& watermarked);

// Reusable buffers of TrainStep.
struct StepBuffers {
  // Decoder input, gradients of logits, of the decoder input, of the
  // watermarked image (total) and of its MSE term.
  Tensor noised, dlogits, dnoised, dimage, dmse;
};

// One Adam step on cover [N,3,H,W] in [-1,1] with message bits `targets`
// (N*L values 0/1) under noise `kind`: encoder, noise, decoder, loss
// image_weight * MSE + BCE, backward through all three, update.
StepResult TrainStep(HiddenModel& model, NetworkAdam& adam, ImageNoise& noise,
                     NoiseKind kind, const Tensor& cover,
                     const std::vector<float>& targets, float image_weight,
                     std::mt19937* rng, StepBuffers* buffers);

// PSNR target after `step` (0-based): the linear ramp from
// target_psnr_start to target_psnr over psnr_ramp_steps, or, with an
// accuracy gate, `current` advanced by one ramp step only when
// `running_accuracy` >= the gate (never past target_psnr).
float NextPsnrTarget(const DecoderTrainingOptions& options, int64_t step,
                     double running_accuracy, float current);

// Runs the whole training on options.device; writes output_path (atomically)
// at the end. Throws Error before reading any photo when the device is
// kCuda and CUDA is unusable.
void TrainDecoder(const DecoderTrainingOptions& options);

// Converts the float RGB pixels (CV_32FC3 in [0, 1], LoadPhotoFolder's)
// [y0,y0+h) x [x0,x0+w) of `photo` into slot b of `batch` [N,3,h,w] in
// [-1,1].
void PhotoToTensor(const cv::Mat& photo, int x0, int y0, int b, Tensor* batch);

}  // namespace watergs
