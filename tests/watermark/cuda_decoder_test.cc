// Parity of the GPU HiDDeN networks (watermark/cuda/cuda_hidden.h) with the
// CPU ones: CudaDecoder's logits and input gradients against Decoder's on
// the shipped decoder and on a tiny random model, the encoder's forward
// pass, one training step (forward, backward, Adam) under the identity and
// three host noise layers (cuda_decoder_training.h), and the trainer's state
// round trip. GPU tests skip without a GPU; the file-refusal test needs none
// (the file is checked before any CUDA call).
//
// Tolerances, relative to the largest magnitude of the CPU values compared:
// 1e-3 through whole networks (8 convolutions, each ~1e-5 relative with
// cuDNN's Winograd/FFT algorithms (see cuda_nn_test.cc), compounded and
// amplified by BatchNorm's 1/std scaling); parameters after the Adam step
// are compared only where the CPU gradient is well above that error (Adam's
// first step is lr * g / (|g| + eps), so a gradient that is rounding noise,
// such as a conv bias before a training-mode BatchNorm, moves its parameter
// by an arbitrary fraction of lr on either side).
#ifdef WATERGS_WITH_CUDA

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "gaussian/cuda/device_buffer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"
#include "watermark/cuda/cuda_decoder_training.h"
#include "watermark/cuda/cuda_hidden.h"
#include "watermark/decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/image_noise.h"

namespace watergs {
namespace {

const std::string kShippedDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/hidden_48.bin";

double MaxAbs(const std::vector<float>& values) {
  double scale = 0.0;
  for (float v : values) scale = std::max(scale, double(std::abs(v)));
  return scale;
}

// |gpu - cpu| <= relative * scale element-wise; reports the worst one.
void ExpectCloseToScale(const std::vector<float>& gpu,
                        const std::vector<float>& cpu, double relative,
                        double scale, const std::string& what) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  double worst = 0.0;
  size_t worst_index = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    ASSERT_TRUE(std::isfinite(gpu[i])) << what << " [" << i << "]";
    const double diff = std::abs(double(gpu[i]) - cpu[i]);
    if (diff > worst) worst = diff, worst_index = i;
  }
  EXPECT_LE(worst, relative * scale + 1e-30)
      << what << ": worst element " << worst_index << " gpu "
      << gpu[worst_index] << " cpu " << cpu[worst_index] << " (scale " << scale
      << ")";
}

// Scale: the largest |cpu| value.
void ExpectClose(const std::vector<float>& gpu, const std::vector<float>& cpu,
                 double relative, const std::string& what) {
  ExpectCloseToScale(gpu, cpu, relative, MaxAbs(cpu), what);
}

// A smooth image with some texture, values in [0,1].
ImageRGB TestImage(int width, int height, std::mt19937* rng) {
  ImageRGB image(width, height);
  std::uniform_real_distribution<float> noise(-0.1f, 0.1f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c)
        image.At(x, y)[c] = std::clamp(
            0.5f + 0.3f * std::sin(0.3f * x + c) * std::cos(0.2f * y) +
                noise(*rng),
            0.f, 1.f);
  return image;
}

std::vector<float> RandomVector(size_t n, std::mt19937* rng) {
  std::normal_distribution<float> dist(0.f, 1.f);
  std::vector<float> v(n);
  for (float& x : v) x = dist(*rng);
  return v;
}

// Tiny model with non-trivial BatchNorm running statistics.
HiddenConfig TinyConfig() {
  HiddenConfig config;
  config.num_bits = 8;
  config.channels = 8;
  config.encoder_blocks = 2;
  config.decoder_blocks = 2;
  return config;
}

void RandomizeRunningStatistics(HiddenModel* model, std::mt19937* rng) {
  std::uniform_real_distribution<float> mean(-0.5f, 0.5f), var(0.5f, 2.f);
  for (Parameter* p : model->AllParameters()) {
    const bool is_mean = p->name.find("running_mean") != std::string::npos;
    const bool is_var = p->name.find("running_var") != std::string::npos;
    for (float& v : p->value) {
      if (is_mean) v = mean(*rng);
      if (is_var) v = var(*rng);
    }
  }
}

// Decoder and CudaDecoder agree on logits and input gradients of images.
void ExpectDecodersAgree(Decoder& cpu, CudaDecoder& gpu, int width, int height,
                         std::mt19937* rng) {
  ASSERT_EQ(gpu.NumBits(), cpu.NumBits());
  for (int round = 0; round < 2; ++round) {
    const ImageRGB image = TestImage(width + round, height, rng);
    const std::vector<float> logits = cpu.Logits(image);
    ExpectClose(gpu.Logits(image), logits, 1e-3, "logits");
    const std::vector<float> dlogits = RandomVector(logits.size(), rng);
    const ImageRGB dimage = cpu.InputGradient(image, dlogits);
    const ImageRGB dimage_gpu = gpu.InputGradient(image, dlogits);
    EXPECT_EQ(dimage_gpu.width, image.width);
    EXPECT_EQ(dimage_gpu.height, image.height);
    ExpectClose(dimage_gpu.data, dimage.data, 1e-3, "input gradient");

    // The device-image path computes the same thing as the host one.
    DeviceBuffer<float> image_gpu, dimage_device(image.data.size());
    image_gpu.Upload(image.data);
    EXPECT_EQ(gpu.LogitsDevice(image_gpu.data(), image.width, image.height),
              gpu.Logits(image));
    gpu.InputGradientDevice(image_gpu.data(), image.width, image.height,
                            dlogits, dimage_device.data());
    std::vector<float> device_result;
    dimage_device.Download(&device_result);
    EXPECT_EQ(device_result, dimage_gpu.data);
  }
}

TEST(CudaDecoderTest, ShippedDecoderMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(31);
  Decoder cpu = Decoder::Load(kShippedDecoder, 48);
  CudaDecoder gpu = CudaDecoder::Load(kShippedDecoder, 48);
  ExpectDecodersAgree(cpu, gpu, 64, 48, &rng);
}

// The TF32 path (cuDNN algorithms rated under default math, cuBLAS TF32
// mode) runs and stays close. TF32 keeps 10 mantissa bits: each input and
// weight is rounded by up to 2^-11 relative, so a convolution's output is
// off by ~1e-3 of its scale; compounded over the 9 layers (inference-mode
// BatchNorm does not renormalise), 2e-2 of the largest logit is a bound;
// the input gradient also passes 9 TF32 backward convolutions and ReLU
// masks that forward noise may flip near 0, hence 5e-2. A wrong layer or
// algorithm is off by the values' whole size.
TEST(CudaDecoderTest, ShippedDecoderWithTf32IsClose) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(33);
  Decoder cpu = Decoder::Load(kShippedDecoder, 48);
  CudaDecoder gpu = CudaDecoder::Load(kShippedDecoder, 48, true);
  const ImageRGB image = TestImage(64, 48, &rng);
  const std::vector<float> logits = cpu.Logits(image);
  ExpectClose(gpu.Logits(image), logits, 2e-2, "TF32 logits");
  const std::vector<float> dlogits = RandomVector(logits.size(), &rng);
  ExpectClose(gpu.InputGradient(image, dlogits).data,
              cpu.InputGradient(image, dlogits).data, 5e-2,
              "TF32 input gradient");
}

TEST(CudaDecoderTest, TinyRandomDecoderMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(37);
  HiddenModel model(TinyConfig(), false, 5);
  RandomizeRunningStatistics(&model, &rng);
  Decoder cpu(&model);
  CudaDecoder gpu(model);
  ExpectDecodersAgree(cpu, gpu, 9, 7, &rng);
  ExpectDecodersAgree(cpu, gpu, 1, 1, &rng);
}

// A decoder moved after a forward pass (its network kept a pointer to the
// source's input) gives the same gradients once the source is gone, by
// move construction and by move assignment.
TEST(CudaDecoderTest, MovedDecoderGivesTheSameGradients) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(45);
  HiddenModel model(TinyConfig(), false, 5);
  const ImageRGB image = TestImage(9, 7, &rng);
  const std::vector<float> dlogits = RandomVector(8, &rng);
  std::vector<float> expected;
  CudaDecoder moved = [&] {
    CudaDecoder source(model);
    expected = source.InputGradient(image, dlogits).data;
    return CudaDecoder(std::move(source));
  }();
  EXPECT_EQ(moved.InputGradient(image, dlogits).data, expected);
  CudaDecoder assigned(model);
  {
    CudaDecoder source(model);
    source.InputGradient(image, dlogits);
    assigned = std::move(source);
  }
  EXPECT_EQ(assigned.InputGradient(image, dlogits).data, expected);
}

// The embedder's in-place patch path: the logits of a rect of a wider device
// image equal those of the cropped image, and its input gradient is added
// into exactly that rect of a gradient image (other pixels untouched); a
// gradient for another patch, or a rect outside the image, is refused.
TEST(CudaDecoderTest, PatchOfAWiderImageEqualsTheCroppedImage) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(47);
  HiddenModel model(TinyConfig(), false, 5);
  RandomizeRunningStatistics(&model, &rng);
  CudaDecoder gpu(model);
  const ImageRGB image = TestImage(13, 10, &rng);
  const PixelRect rect{3, 2, 7, 5};
  ImageRGB cropped(rect.width, rect.height);
  for (int y = 0; y < rect.height; ++y)
    for (int x = 0; x < rect.width; ++x)
      for (int c = 0; c < 3; ++c)
        cropped.At(x, y)[c] = image.At(rect.x0 + x, rect.y0 + y)[c];
  const std::vector<float> dlogits = RandomVector(8, &rng);
  const std::vector<float> logits = gpu.Logits(cropped);
  const ImageRGB dcropped = gpu.InputGradient(cropped, dlogits);

  DeviceBuffer<float> image_gpu, dimage_gpu;
  image_gpu.Upload(image.data);
  const std::vector<float> base = RandomVector(image.data.size(), &rng);
  dimage_gpu.Upload(base);
  EXPECT_EQ(gpu.LogitsDevicePatch(image_gpu.data(), image.width, rect), logits);
  gpu.AddInputGradientDevicePatch(dlogits, dimage_gpu.data(), image.width,
                                  rect);
  std::vector<float> dimage;
  dimage_gpu.Download(&dimage);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const size_t i = (size_t(y) * image.width + x) * 3 + c;
        const bool inside = x >= rect.x0 && x < rect.x0 + rect.width &&
                            y >= rect.y0 && y < rect.y0 + rect.height;
        const float expected =
            inside ? base[i] + dcropped.At(x - rect.x0, y - rect.y0)[c]
                   : base[i];
        ASSERT_EQ(dimage[i], expected) << x << "," << y << "," << c;
      }
  EXPECT_THROW(gpu.AddInputGradientDevicePatch(dlogits, dimage_gpu.data(),
                                               image.width, {0, 0, 7, 5}),
               Error);
  EXPECT_THROW(
      gpu.LogitsDevicePatch(image_gpu.data(), image.width, {8, 0, 7, 5}),
      Error);
}

TEST(CudaDecoderTest, WrongLogitGradientCountIsRefused) {
  WATERGS_REQUIRE_CUDA();
  HiddenModel model(TinyConfig(), false, 5);
  CudaDecoder gpu(model);
  std::mt19937 rng(41);
  EXPECT_THROW(gpu.InputGradient(TestImage(4, 4, &rng), {1.f, 2.f}), Error);
}

// Needs no GPU: the weights file is read and checked before any CUDA call.
TEST(CudaDecoderTest, TruncatedFileIsRefusedNamingIt) {
  std::ifstream in(kShippedDecoder, std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 100u);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_cuda_decoder_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "decoder_48.bin").string();
  {
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size() - 100));
  }
  try {
    CudaDecoder::Load(path);
    ADD_FAILURE() << "truncated copy was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// [n,3,h,w] in [-1,1].
Tensor RandomCover(int n, int h, int w, std::mt19937* rng) {
  Tensor cover(n, 3, h, w);
  std::uniform_real_distribution<float> dist(-0.9f, 0.9f);
  for (float& v : cover.data) v = dist(*rng);
  return cover;
}

std::vector<float> ValuesOf(const std::vector<Parameter*>& params,
                            const std::string& name) {
  for (const Parameter* p : params)
    if (p->name == name) return p->value;
  ADD_FAILURE() << "no parameter " << name;
  return {};
}

TEST(CudaEncoderTest, ForwardMatchesCpuInBothModes) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(43);
  const HiddenConfig config = TinyConfig();
  HiddenModel model(config, true, 9);
  RandomizeRunningStatistics(&model, &rng);
  CudaNnContext context;
  CudaHiddenModel gpu(&context, model);
  const Tensor cover = RandomCover(2, 10, 9, &rng);
  std::vector<float> message(2 * config.num_bits);
  for (size_t i = 0; i < message.size(); ++i) message[i] = i % 3 ? 1.f : -1.f;
  DeviceTensor cover_gpu;
  cover_gpu.Upload(cover);
  DeviceBuffer<float> message_gpu;
  message_gpu.Upload(message);
  for (bool training : {false, true}) {
    const Tensor& wm = model.encoder->Forward(cover, message, training);
    Tensor wm_gpu;
    gpu.encoder->Forward(cover_gpu, message_gpu, training).Download(&wm_gpu);
    ExpectClose(wm_gpu.data, wm.data, 1e-3,
                training ? "watermarked (training)" : "watermarked");
  }
  // The training pass moved the running statistics on both.
  HiddenModel copy(config, true, 9);
  gpu.CopyToHost(&copy);
  for (const char* name : {"encoder.block1.bn.running_mean",
                           "encoder.after_concat.bn.running_var"}) {
    ExpectClose(ValuesOf(copy.AllParameters(), name),
                ValuesOf(model.AllParameters(), name), 1e-4, name);
  }
}

// Both networks' backward passes on their own (no optimiser, no noise):
// every parameter gradient and the decoder's image gradient, in training
// and inference mode. A conv bias before a training-mode BatchNorm has
// gradient 0 up to rounding (BN removes the mean), so it is compared at the
// scale of its conv weight gradient.
TEST(CudaHiddenBackwardTest, EveryGradientMatchesCpuInBothModes) {
  WATERGS_REQUIRE_CUDA();
  const HiddenConfig config = TinyConfig();
  for (bool training : {false, true}) {
    std::mt19937 rng(59);
    HiddenModel model(config, true, 19);
    RandomizeRunningStatistics(&model, &rng);
    CudaNnContext context;
    CudaHiddenModel gpu(&context, model);
    const Tensor cover = RandomCover(3, 9, 11, &rng);
    std::vector<float> message(3 * config.num_bits);
    for (size_t i = 0; i < message.size(); ++i) message[i] = i % 4 ? 1.f : -1.f;
    Tensor dwatermarked(3, 3, 9, 11), dlogits(3, config.num_bits, 1, 1);
    for (Tensor* t : {&dwatermarked, &dlogits})
      t->data = RandomVector(t->size(), &rng);
    DeviceTensor cover_gpu, dwatermarked_gpu, dlogits_gpu;
    cover_gpu.Upload(cover);
    dwatermarked_gpu.Upload(dwatermarked);
    dlogits_gpu.Upload(dlogits);
    DeviceBuffer<float> message_gpu;
    message_gpu.Upload(message);

    // Encoder: forward, backward to its weights.
    model.encoder->Forward(cover, message, training);
    model.encoder->Backward(dwatermarked, training);
    gpu.encoder->Forward(cover_gpu, message_gpu, training);
    gpu.encoder->Backward(dwatermarked_gpu, training);
    // Decoder on the cover: weights and image gradient.
    Tensor dimage;
    DeviceTensor dimage_gpu;
    model.decoder->Forward(cover, training);
    model.decoder->Backward(dlogits, &dimage, true, training);
    gpu.decoder->Forward(cover_gpu, training);
    gpu.decoder->Backward(dlogits_gpu, &dimage_gpu, true, training);
    Tensor dimage_host;
    dimage_gpu.Download(&dimage_host);
    const std::string mode = training ? " (training)" : " (inference)";
    ExpectClose(dimage_host.data, dimage.data, 1e-3, "decoder dimage" + mode);

    HiddenModel copy(config, true, 19);
    gpu.CopyToHost(&copy);
    const std::vector<Parameter*> cpu_params = model.AllParameters();
    const std::vector<Parameter*> gpu_params = copy.AllParameters();
    ASSERT_EQ(gpu_params.size(), cpu_params.size());
    for (size_t k = 0; k < cpu_params.size(); ++k) {
      const Parameter& c = *cpu_params[k];
      if (!c.trainable) continue;
      const bool bias_before_bn =
          training && c.name.find(".conv.bias") != std::string::npos;
      const double scale =
          bias_before_bn ? MaxAbs(cpu_params[k - 1]->grad) : MaxAbs(c.grad);
      // A real gradient (all zeros on both sides would prove nothing).
      if (!bias_before_bn) {
        EXPECT_GT(MaxAbs(c.grad), 0.0) << c.name << mode;
      }
      ExpectCloseToScale(gpu_params[k]->grad, c.grad, 1e-3, scale,
                         c.name + " gradient" + mode);
    }
  }
}

class CudaTrainStepTest : public ::testing::TestWithParam<NoiseKind> {};

// One TrainStep on the CPU and one CudaDecoderTrainer step from the same
// weights, batch, message and noise draw.
TEST_P(CudaTrainStepTest, OneStepMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  const NoiseKind kind = GetParam();
  std::mt19937 rng(47);
  const HiddenConfig config = TinyConfig();
  const float learning_rate = 1e-3f, image_weight = 0.7f;
  HiddenModel model(config, true, 13);
  NetworkAdam adam(model.AllParameters(), learning_rate);
  CudaDecoderTrainer trainer(model, adam);
  const Tensor cover = RandomCover(3, 12, 12, &rng);
  std::vector<float> targets(3 * config.num_bits);
  for (size_t i = 0; i < targets.size(); ++i) targets[i] = (i * 7 % 5) < 2;
  std::vector<std::vector<float>> initial;
  for (const Parameter* p : model.AllParameters()) initial.push_back(p->value);

  ImageNoise noise, gpu_noise;
  StepBuffers buffers;
  std::mt19937 noise_rng(1), gpu_noise_rng(1);
  const StepResult result = TrainStep(model, adam, noise, kind, cover, targets,
                                      image_weight, &noise_rng, &buffers);
  const StepResult gpu_result = trainer.Step(gpu_noise, kind, cover, targets,
                                             image_weight, &gpu_noise_rng);
  EXPECT_NEAR(gpu_result.bce, result.bce, 1e-3 * result.bce);
  EXPECT_NEAR(gpu_result.psnr, result.psnr, 1e-3 * result.psnr);
  EXPECT_NEAR(gpu_result.accuracy, result.accuracy, 1.0 / targets.size());

  HiddenModel after(config, true, 13);
  NetworkAdam adam_after(after.AllParameters(), learning_rate);
  trainer.CopyToHost(&after, &adam_after);
  EXPECT_EQ(adam_after.step, adam.step);
  const std::vector<Parameter*> gpu_params = after.AllParameters();
  const std::vector<Parameter*> cpu_params = model.AllParameters();
  ASSERT_EQ(gpu_params.size(), cpu_params.size());
  for (size_t k = 0; k < cpu_params.size(); ++k) {
    const Parameter& c = *cpu_params[k];
    const Parameter& g = *gpu_params[k];
    if (!c.trainable) {
      ExpectClose(g.value, c.value, 1e-4, c.name + " (running statistic)");
      continue;
    }
    // A conv bias before a training-mode BatchNorm has gradient 0 (BN
    // removes the mean): both sides hold rounding noise, compared at the
    // scale of the block's conv weight gradient.
    const bool bias_before_bn = c.name.find(".conv.bias") != std::string::npos;
    const double grad_scale =
        bias_before_bn ? MaxAbs(cpu_params[k - 1]->grad) : MaxAbs(c.grad);
    ExpectCloseToScale(g.grad, c.grad, 1e-3, grad_scale, c.name + " gradient");
    // Adam moved each parameter with a clear gradient by ~lr * sign(g).
    for (size_t i = 0; i < c.size(); ++i) {
      if (std::abs(c.grad[i]) < 1e-2 * grad_scale || std::abs(c.grad[i]) < 1e-6)
        continue;
      EXPECT_NEAR(g.value[i], c.value[i],
                  1e-2 * learning_rate + 1e-6 * std::abs(c.value[i]))
          << c.name << " [" << i << "] after Adam";
      EXPECT_NE(c.value[i], initial[k][i]) << c.name << " did not move";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Noise, CudaTrainStepTest,
                         ::testing::Values(NoiseKind::kIdentity,
                                           NoiseKind::kCrop,
                                           NoiseKind::kDropout,
                                           NoiseKind::kBlur));

// Weights, running statistics and Adam state survive the trip to the device
// and back unchanged (what a checkpoint or validation in a GPU run relies
// on).
TEST(CudaDecoderTrainerTest, StateRoundTripIsExact) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(53);
  const HiddenConfig config = TinyConfig();
  HiddenModel model(config, true, 17);
  RandomizeRunningStatistics(&model, &rng);
  NetworkAdam adam(model.AllParameters(), 2e-3f);
  ImageNoise noise;
  StepBuffers buffers;
  std::vector<float> targets(2 * config.num_bits, 1.f);
  TrainStep(model, adam, noise, NoiseKind::kIdentity,
            RandomCover(2, 8, 8, &rng), targets, 0.5f, &rng, &buffers);
  CudaDecoderTrainer trainer(model, adam);
  HiddenModel copy(config, true, 99);
  NetworkAdam copy_adam(copy.AllParameters(), 1.f);
  trainer.CopyToHost(&copy, &copy_adam);
  const std::vector<Parameter*> a = model.AllParameters();
  const std::vector<Parameter*> b = copy.AllParameters();
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(b[k]->value, a[k]->value) << a[k]->name;
    EXPECT_EQ(copy_adam.m[k], adam.m[k]) << a[k]->name;
    EXPECT_EQ(copy_adam.v[k], adam.v[k]) << a[k]->name;
  }
  EXPECT_EQ(copy_adam.step, adam.step);
  EXPECT_EQ(copy_adam.learning_rate, adam.learning_rate);
}

}  // namespace
}  // namespace watergs

#endif  // WATERGS_WITH_CUDA
