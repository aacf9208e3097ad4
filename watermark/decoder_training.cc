// HiDDeN encoder/decoder training (see decoder_training.h).
#include "watermark/decoder_training.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "gaussian/backend.h"
#include "gaussian/util/error.h"
#include "gaussian/util/progress.h"
#include "watermark/backend.h"
#include "watermark/image_reading.h"

namespace watergs {
namespace {

constexpr char kCheckpointKind[] = "hidden-checkpoint";

// Random message bits (0/1) for n images and their +-1 encoder input.
void RandomMessages(int n, int bits, std::mt19937* rng,
                    std::vector<float>* targets, std::vector<float>* signs) {
  targets->resize(size_t(n) * bits);
  signs->resize(targets->size());
  std::bernoulli_distribution coin(0.5);
  for (size_t i = 0; i < targets->size(); ++i) {
    (*targets)[i] = coin(*rng) ? 1.f : 0.f;
    (*signs)[i] = 2.f * (*targets)[i] - 1.f;
  }
}

void SaveCheckpoint(const std::string& path, HiddenModel& model,
                    const NetworkAdam& adam, int64_t step, float image_weight,
                    float psnr_target, const DecoderTrainingOptions& options) {
  NetworkFile file = HiddenModelToFile(model, true);
  file.kind = kCheckpointKind;
  file.meta.emplace_back("step", step);
  file.meta.emplace_back("adam_step", adam.step);
  file.meta.emplace_back("crop", options.crop);
  file.meta.emplace_back("seed", options.seed);
  // Adapted image weight, stored in millionths.
  file.meta.emplace_back("image_weight_micro",
                         int64_t(std::llround(double(image_weight) * 1e6)));
  // Current PSNR target of the accuracy-gated ramp, in millidecibels.
  file.meta.emplace_back("psnr_target_milli",
                         int64_t(std::llround(double(psnr_target) * 1e3)));
  const auto& params = adam.params();
  for (size_t k = 0; k < params.size(); ++k) {
    if (!params[k]->trainable) continue;
    file.tensors.push_back(
        {"adam.m." + params[k]->name, params[k]->shape, adam.m[k]});
    file.tensors.push_back(
        {"adam.v." + params[k]->name, params[k]->shape, adam.v[k]});
  }
  WriteNetworkFile(path, file);
}

// Restores model weights, Adam state and counters; returns the step.
int64_t LoadCheckpoint(const std::string& path, HiddenModel* model,
                       NetworkAdam* adam, float* image_weight,
                       float* psnr_target,
                       const DecoderTrainingOptions& options) {
  const NetworkFile file = ReadNetworkFile(path);
  if (file.kind != kCheckpointKind) FailAt(path, "not a training checkpoint");
  auto loaded = HiddenModelFromFile(path, file, true, options.config.num_bits);
  if (loaded->config.channels != options.config.channels)
    FailAt(path, "checkpoint architecture differs from the options");
  std::vector<Parameter*> dst = model->AllParameters();
  std::vector<Parameter*> src = loaded->AllParameters();
  for (size_t k = 0; k < dst.size(); ++k) dst[k]->value = src[k]->value;
  const auto& params = adam->params();
  for (size_t k = 0; k < params.size(); ++k) {
    if (!params[k]->trainable) continue;
    const TensorRecord* m = file.Find("adam.m." + params[k]->name);
    const TensorRecord* v = file.Find("adam.v." + params[k]->name);
    if (!m || !v || m->values.size() != params[k]->size() ||
        v->values.size() != params[k]->size())
      FailAt(path, "checkpoint lacks optimiser state for " + params[k]->name);
    adam->m[k] = m->values;
    adam->v[k] = v->values;
  }
  adam->step = file.Meta("adam_step", path);
  *image_weight = float(file.Meta("image_weight_micro", path) * 1e-6);
  // Checkpoints written before the gated ramp existed lack the field.
  for (const auto& [key, value] : file.meta)
    if (key == "psnr_target_milli") *psnr_target = float(value * 1e-3);
  return file.Meta("step", path);
}

// Training steps on options.device. On the GPU the model and Adam state live
// on the device between steps; SyncToHost brings them back into the CPU
// model and optimiser, which checkpoints, validation and the final save
// read. On the CPU every call is exactly TrainStep.
class StepRunner {
 public:
  StepRunner(HiddenModel& model, NetworkAdam& adam,
             const DecoderTrainingOptions& options)
      : model_(model), adam_(adam) {
    if (options.device != Device::kCuda) return;
    // Built after any resume: the device starts from the loaded state.
    gpu_ = MakeGpuDecoderTrainer(model, adam, options.allow_tf32);
    std::cerr << "train_decoder: steps on " << GpuDescription()
              << (options.allow_tf32 ? " (TF32 allowed)" : " (float32)")
              << "\n";
  }

  // cover [N,3,H,W] in [-1,1], targets N*L bits: one step (see TrainStep).
  StepResult Step(NoiseKind kind, const Tensor& cover,
                  const std::vector<float>& targets, float image_weight,
                  std::mt19937* rng) {
    if (gpu_) {
      device_ahead_ = true;
      return gpu_->Step(noise_, kind, cover, targets, image_weight, rng);
    }
    return TrainStep(model_, adam_, noise_, kind, cover, targets, image_weight,
                     rng, &buffers_);
  }

  // Makes the CPU model and optimiser hold the latest state.
  void SyncToHost() {
    if (gpu_ && device_ahead_) gpu_->CopyToHost(&model_, &adam_);
    device_ahead_ = false;
  }

 private:
  // The CPU model and optimiser: the trained state on the CPU, a copy
  // refreshed by SyncToHost on the GPU.
  HiddenModel& model_;
  NetworkAdam& adam_;
  // Noise layers on the host (on the GPU: every layer but identity).
  ImageNoise noise_;
  // CPU step buffers.
  StepBuffers buffers_;
  // Whether the device has steps the CPU copy lacks.
  bool device_ahead_ = false;
  // Device state (null on the CPU).
  std::unique_ptr<DeviceDecoderTrainer> gpu_;
};

// Fails with one line unless options.device can run (CUDA: backend built
// and a GPU visible).
void CheckDevice(const DecoderTrainingOptions& options) {
  std::string why;
  if (options.device == Device::kCuda && !CudaAvailable(&why))
    Fail("train_decoder --device cuda: " + why);
}

}  // namespace

double BitAccuracy(const Tensor& logits, const std::vector<float>& targets) {
  size_t correct = 0;
  for (size_t i = 0; i < logits.size(); ++i)
    correct += (logits.data[i] > 0.f) == (targets[i] > 0.5f);
  return double(correct) / double(logits.size());
}

double BatchPsnr(const Tensor& cover, const Tensor& watermarked) {
  double sum = 0.0;
  for (size_t i = 0; i < cover.size(); ++i) {
    const double d =
        (std::clamp(watermarked.data[i], -1.f, 1.f) - cover.data[i]) * 0.5;
    sum += d * d;
  }
  const double mse = std::max(sum / double(cover.size()), 1e-12);
  return -10.0 * std::log10(mse);
}

float NextPsnrTarget(const DecoderTrainingOptions& options, int64_t step,
                     double running_accuracy, float current) {
  const float start = options.target_psnr_start, end = options.target_psnr;
  if (options.psnr_ramp_steps <= 0) return end;
  const float per_step = (end - start) / float(options.psnr_ramp_steps);
  if (options.accuracy_gate > 0) {
    if (running_accuracy < options.accuracy_gate) return current;
    return per_step >= 0 ? std::min(end, current + per_step)
                         : std::max(end, current + per_step);
  }
  if (step >= options.psnr_ramp_steps) return end;
  return start + per_step * float(step);
}

void PhotoToTensor(const cv::Mat& photo, int x0, int y0, int b, Tensor* batch) {
  if (photo.type() != CV_32FC3) {
    Fail("PhotoToTensor: expected a float RGB photo (CV_32FC3)");
  }
  for (int y = 0; y < batch->h; ++y) {
    const float* row = photo.ptr<float>(y0 + y) + 3 * x0;
    for (int x = 0; x < batch->w; ++x)
      for (int c = 0; c < 3; ++c)
        batch->Plane(b, c)[size_t(y) * batch->w + x] =
            2.f * row[3 * x + c] - 1.f;
  }
}

std::vector<cv::Mat> LoadPhotoFolder(const std::string& dir,
                                     std::vector<std::string>* paths) {
  const std::vector<std::string> files = ListImageFiles(dir, true);
  if (files.empty()) FailAt(dir, "no .jpg or .png photos found");
  std::vector<cv::Mat> photos;
  for (const std::string& path : files) photos.push_back(DecodeImageFile(path));
  if (paths) *paths = files;
  return photos;
}

ValidationResult Validate(HiddenModel& model,
                          const std::vector<cv::Mat>& photos, int crop,
                          uint32_t seed) {
  ValidationResult result;
  const NoiseKind kinds[] = {NoiseKind::kIdentity, NoiseKind::kCrop,
                             NoiseKind::kDropout,  NoiseKind::kResize,
                             NoiseKind::kBlur,     NoiseKind::kJpeg};
  std::vector<double> correct(6, 0.0);
  std::mt19937 rng(seed);
  ImageNoise noise;
  Tensor cover, noised;
  std::vector<float> targets, signs;
  for (const cv::Mat& photo : photos) {
    const int h = crop > 0 ? std::min(crop, photo.rows) : photo.rows;
    const int w = crop > 0 ? std::min(crop, photo.cols) : photo.cols;
    cover.Resize(1, 3, h, w);
    PhotoToTensor(photo, (photo.cols - w) / 2, (photo.rows - h) / 2, 0, &cover);
    RandomMessages(1, model.config.num_bits, &rng, &targets, &signs);
    Tensor watermarked = model.encoder->Forward(cover, signs, false);
    for (float& v : watermarked.data) v = std::clamp(v, -1.f, 1.f);
    result.psnr += BatchPsnr(cover, watermarked);
    for (int k = 0; k < 6; ++k) {
      noise.Forward(kinds[k], watermarked, cover, &noised, &rng);
      correct[k] += BitAccuracy(model.decoder->Forward(noised, false), targets);
    }
    ++result.images;
  }
  result.psnr /= std::max(result.images, 1);
  for (int k = 0; k < 6; ++k)
    result.accuracy.emplace_back(kinds[k],
                                 correct[k] / std::max(result.images, 1));
  return result;
}

std::string FormatValidation(const ValidationResult& result) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(2);
  s << "held-out " << result.images << " photos: PSNR " << result.psnr
    << " dB | bit accuracy";
  for (const auto& [kind, accuracy] : result.accuracy)
    s << " " << NoiseName(kind) << " " << 100.0 * accuracy << "%";
  return s.str();
}

StepResult TrainStep(HiddenModel& model, NetworkAdam& adam, ImageNoise& noise,
                     NoiseKind kind, const Tensor& cover,
                     const std::vector<float>& targets, float image_weight,
                     std::mt19937* rng, StepBuffers* buf) {
  std::vector<float> signs(targets.size());
  for (size_t i = 0; i < targets.size(); ++i) signs[i] = 2.f * targets[i] - 1.f;
  adam.ZeroGrad();
  const Tensor& watermarked = model.encoder->Forward(cover, signs, true);
  noise.Forward(kind, watermarked, cover, &buf->noised, rng);
  const Tensor& logits = model.decoder->Forward(buf->noised, true);
  StepResult result;
  result.bce = BceWithLogits(logits, targets, &buf->dlogits);
  result.accuracy = BitAccuracy(logits, targets);
  result.psnr = BatchPsnr(cover, watermarked);
  model.decoder->Backward(buf->dlogits, &buf->dnoised, true, true);
  noise.Backward(buf->dnoised, &buf->dimage);
  MseLoss(watermarked, cover, &buf->dmse);
  for (size_t i = 0; i < buf->dimage.size(); ++i)
    buf->dimage.data[i] += image_weight * buf->dmse.data[i];
  model.encoder->Backward(buf->dimage, true);
  adam.Step();
  return result;
}

void TrainDecoder(const DecoderTrainingOptions& options) {
  CheckDevice(options);
  const std::vector<cv::Mat> photos = LoadPhotoFolder(options.image_path);
  std::vector<cv::Mat> held_out;
  if (!options.validation_path.empty())
    held_out = LoadPhotoFolder(options.validation_path);
  const int crop = options.crop;
  std::vector<const cv::Mat*> usable;
  for (const cv::Mat& p : photos)
    if (p.rows >= crop && p.cols >= crop) usable.push_back(&p);
  if (usable.empty())
    FailAt(options.image_path, "no photo is at least " + std::to_string(crop) +
                                   " pixels on each side");

  HiddenModel model(options.config, true, options.seed);
  std::vector<Parameter*> params = model.AllParameters();
  NetworkAdam adam(params, options.learning_rate);
  float image_weight = options.image_weight;
  const std::string checkpoint = options.output_path + ".ckpt";
  int64_t step = 0;
  float psnr_target = options.target_psnr_start;
  if (options.resume && std::filesystem::exists(checkpoint)) {
    step = LoadCheckpoint(checkpoint, &model, &adam, &image_weight,
                          &psnr_target, options);
    std::cerr << "resumed from " << checkpoint << " at step " << step << "\n";
  }
  const int steps_per_epoch =
      options.steps_per_epoch > 0
          ? options.steps_per_epoch
          : std::max<int>(1, int(usable.size()) / options.batch_size);
  const int64_t total = int64_t(steps_per_epoch) * options.epochs;
  const int bits = options.config.num_bits;

  StepRunner runner(model, adam, options);
  Tensor cover(options.batch_size, 3, crop, crop);
  std::vector<float> targets, signs;
  ProgressBar progress("train_decoder", total, step);
  double running_psnr = 0, running_acc = 0, running_bce = 0;
  for (; step < total; ++step) {
    // Reseeded per step so that a resumed run draws what it would have.
    std::mt19937 rng(options.seed * 1000003u + uint32_t(step));
    for (int b = 0; b < options.batch_size; ++b) {
      const cv::Mat& p = *usable[std::uniform_int_distribution<size_t>(
          0, usable.size() - 1)(rng)];
      const int x0 = std::uniform_int_distribution<int>(0, p.cols - crop)(rng);
      const int y0 = std::uniform_int_distribution<int>(0, p.rows - crop)(rng);
      PhotoToTensor(p, x0, y0, b, &cover);
    }
    RandomMessages(options.batch_size, bits, &rng, &targets, &signs);
    const NoiseKind kind = options.noise[std::uniform_int_distribution<size_t>(
        0, options.noise.size() - 1)(rng)];
    const StepResult r = runner.Step(kind, cover, targets, image_weight, &rng);
    const double psnr = r.psnr, bce = r.bce;
    if (options.on_step) options.on_step(step, r);

    const double a = step == 0 ? 1.0 : 0.05;
    running_psnr += a * (psnr - running_psnr);
    running_bce += a * (bce - running_bce);
    running_acc += a * (r.accuracy - running_acc);
    if (options.target_psnr > 0) {
      psnr_target = NextPsnrTarget(options, step, running_acc, psnr_target);
      image_weight =
          std::clamp(image_weight * (psnr < psnr_target ? 1.02f : 1.f / 1.02f),
                     1e-4f, 1e4f);
    }
    std::ostringstream status;
    status.setf(std::ios::fixed);
    status.precision(3);
    status << "bce " << running_bce << " acc " << 100 * running_acc << "% psnr "
           << running_psnr << " w_img " << image_weight;
    if (options.target_psnr > 0) status << " target " << psnr_target;
    progress.Update(step + 1, status.str());

    const bool epoch_end = (step + 1) % steps_per_epoch == 0;
    const bool out_of_time =
        options.max_minutes > 0 &&
        progress.ElapsedSeconds() > options.max_minutes * 60;
    const bool save = epoch_end || out_of_time ||
                      (options.checkpoint_every > 0 &&
                       (step + 1) % options.checkpoint_every == 0);
    // Every epoch end saves, so validation reads the synced model too.
    if (save) runner.SyncToHost();
    if (save)
      SaveCheckpoint(checkpoint, model, adam, step + 1, image_weight,
                     psnr_target, options);
    if (epoch_end && !held_out.empty())
      std::cout << "epoch " << (step + 1) / steps_per_epoch << ": "
                << FormatValidation(
                       Validate(model, held_out, options.validation_crop, 7))
                << std::endl;
    if (out_of_time) {
      std::cerr << "\nstopping after --max_minutes " << options.max_minutes
                << " at step " << step + 1 << "\n";
      ++step;
      break;
    }
  }
  progress.Finish();
  runner.SyncToHost();
  SaveHiddenModel(options.output_path, model, true);
  if (!held_out.empty())
    std::cout << "final: "
              << FormatValidation(
                     Validate(model, held_out, options.validation_crop, 7))
              << std::endl;
}

}  // namespace watergs
