// Decoder benchmark, for every decoder kind a weights file can hold.
//
// HiDDeN decoder ("hidden-model" files): frozen-decoder forward + input-
// gradient time at 128x128 and 256x256 with its GFLOP/s; the 64->64 3x3
// convolution layer against Eigen's own float matrix product of the same
// shape, measured in the same run; and training throughput (images/s) of the
// default configuration (crop 128, batch 8, identity noise, 48 bits). With
// --device cuda: CudaDecoder Logits and InputGradient at 128x128 and 256x256,
// and CudaDecoderTrainer steps at the default configuration and at the
// paper's (crop 256, batch 16), each in float32 and with TF32 tensor cores
// allowed; first the host work of a GPU training step (batch assembly, host
// noise layers), which needs no GPU.
//
// Random-feature decoder ("feature-decoder" files, the shipped default):
// Logits and forward + input gradient at 128x128, 256x256 and a 1280x800
// frame (what `embed --crop_size 0` decodes), with GFLOP/s; with --device
// cuda the same for CudaFeatureDecoder, in float32 and with TF32 allowed.
//
// --device cuda without a usable GPU says why on one line and times the CPU.
// Medians of repeated runs.
//
// Usage: decoder_benchmark [--device cpu|cuda|auto] [--repeats N]
//                          [WEIGHTS.bin ...]
// Without WEIGHTS: a randomly initialised decoder of each kind.
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "benchmarks/benchmark_util.h"
#include "gaussian/backend.h"
#include "gaussian/device.h"
#include "gaussian/util/error.h"
#include "watermark/backend.h"
#include "watermark/decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder.h"
#include "watermark/network_file.h"

namespace {

using watergs::bench::MedianSeconds;

using Clock = std::chrono::steady_clock;

// A HiDDeN model from `weights` (random weights when empty).
std::unique_ptr<watergs::HiddenModel> HiddenOf(const std::string& weights) {
  using namespace watergs;
  return weights.empty()
             ? std::make_unique<HiddenModel>(HiddenConfig(), true, 1)
             : LoadHiddenModel(weights, true);
}

// CPU timings of a HiDDeN decoder (the README's figures).
int RunCpu(const std::string& weights, int repeats) {
  using namespace watergs;
  HiddenConfig config;
  std::unique_ptr<HiddenModel> model = HiddenOf(weights);
  std::printf(
      "decoder_benchmark: hidden-model, %d bits, %d channels, %s, %d threads "
      "max\n",
      model->config.num_bits, model->config.channels,
      weights.empty() ? "random weights" : weights.c_str(), Eigen::nbThreads());

  // Frozen decoder: forward + input gradient (backward-data of every layer).
  Decoder decoder(model.get());
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (int size : {128, 256}) {
    ImageRGB image(size, size);
    for (float& v : image.data) v = unit(rng);
    std::vector<float> dlogits(model->config.num_bits, 0.01f);
    ImageRGB grad;
    const double seconds = MedianSeconds(repeats, [&] {
      image.data[0] = unit(rng);  // defeat the forward cache
      decoder.InputGradient(image, dlogits, &grad);
    });
    const double flops =
        2.0 * 2.0 * double(model->decoder->MacsPerPixel()) * size * size;
    std::printf(
        "decoder forward+input-gradient %dx%d: %.1f ms median, %.1f "
        "GFLOP/s (%.2f GFLOP)\n",
        size, size, 1e3 * seconds, flops / seconds * 1e-9, flops * 1e-9);
  }

  // One 64->64 3x3 conv layer (im2col + GEMM) vs Eigen's GEMM of that shape.
  for (int size : {128, 256}) {
    Conv2d conv("bench", 64, 64, 3, &rng);
    Tensor x(1, 64, size, size), y, dx;
    for (float& v : x.data) v = unit(rng);
    using RowMatrix =
        Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    RowMatrix a = RowMatrix::Random(64, 576),
              b = RowMatrix::Random(576, size * size), c(64, size * size);
    // Interleaved single runs, so that load from other processes hits the
    // three measurements alike; medians over 3 x repeats.
    std::vector<double> fwd, bwd, mm;
    auto timed = [](auto&& f) {
      const auto start = Clock::now();
      f();
      return std::chrono::duration<double>(Clock::now() - start).count();
    };
    conv.Forward(x, &y);
    conv.Backward(x, y, &dx, false);
    c.noalias() = a * b;
    for (int r = 0; r < 3 * repeats; ++r) {
      fwd.push_back(timed([&] { conv.Forward(x, &y); }));
      bwd.push_back(timed([&] { conv.Backward(x, y, &dx, false); }));
      mm.push_back(timed([&] { c.noalias() = a * b; }));
    }
    auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const double conv_fwd = median(fwd), conv_bwd = median(bwd),
                 gemm = median(mm);
    const double flops = 2.0 * 64 * 576 * size * size;
    std::printf(
        "conv3x3 64->64 %dx%d: forward %.1f GFLOP/s, backward-data %.1f "
        "GFLOP/s | Eigen GEMM 64x576x%d %.1f GFLOP/s | forward at "
        "%.0f%%, backward-data at %.0f%% of GEMM\n",
        size, size, flops / conv_fwd * 1e-9, flops / conv_bwd * 1e-9,
        size * size, flops / gemm * 1e-9, 100.0 * gemm / conv_fwd,
        100.0 * gemm / conv_bwd);
  }

  // Training throughput, default configuration.
  {
    HiddenModel train_model(config, true, 2);
    std::vector<Parameter*> params = train_model.AllParameters();
    NetworkAdam adam(params, 1e-3f);
    ImageNoise noise;
    StepBuffers buffers;
    const int batch = 8, crop = 128;
    Tensor cover(batch, 3, crop, crop);
    for (float& v : cover.data) v = 2.f * unit(rng) - 1.f;
    std::vector<float> targets(size_t(batch) * config.num_bits);
    for (float& t : targets) t = unit(rng) < 0.5f ? 0.f : 1.f;
    const double seconds = MedianSeconds(std::max(1, repeats / 2), [&] {
      TrainStep(train_model, adam, noise, NoiseKind::kIdentity, cover, targets,
                0.7f, &rng, &buffers);
    });
    std::printf(
        "training (crop %d, batch %d, identity): %.2f s/step, %.2f "
        "images/s\n",
        crop, batch, seconds, batch / seconds);
  }
  return 0;
}

// A [batch,3,crop,crop] cover in [-1,1] and random message bits.
void RandomBatch(int batch, int crop, int bits, std::mt19937* rng,
                 watergs::Tensor* cover, std::vector<float>* targets) {
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  cover->Resize(batch, 3, crop, crop);
  for (float& v : cover->data) v = 2.f * unit(*rng) - 1.f;
  targets->resize(size_t(batch) * bits);
  for (float& t : *targets) t = unit(*rng) < 0.5f ? 0.f : 1.f;
}

// Host work of one GPU training step at crop 256, batch 16 (runs
// anywhere): crop assembly from decoded photos, and each host noise layer's
// forward + backward (CudaTrainStep runs every layer but identity on the
// CPU's ImageNoise).
void HostWorkPerStep(int repeats) {
  using namespace watergs;
  const int batch = 16, crop = 256;
  std::mt19937 rng(5);
  cv::Mat photo(384, 614, CV_32FC3);
  cv::randu(photo, cv::Scalar::all(0), cv::Scalar::all(1));
  Tensor cover(batch, 3, crop, crop), watermarked, noised, dimage;
  const double assembly = MedianSeconds(repeats, [&] {
    for (int b = 0; b < batch; ++b)
      PhotoToTensor(photo, 7 * b % (photo.cols - crop), 3 * b, b, &cover);
  });
  std::printf(
      "host work per step (crop %d, batch %d): "
      "batch assembly %.1f ms",
      crop, batch, 1e3 * assembly);
  std::vector<float> unused;
  RandomBatch(batch, crop, 1, &rng, &watermarked, &unused);
  ImageNoise noise;
  for (NoiseKind kind :
       {NoiseKind::kCrop, NoiseKind::kDropout, NoiseKind::kResize,
        NoiseKind::kBlur, NoiseKind::kJpeg}) {
    const double seconds = MedianSeconds(repeats, [&] {
      noise.Forward(kind, watermarked, cover, &noised, &rng);
      noise.Backward(noised, &dimage);
    });
    std::printf(" | %s %.1f ms", NoiseName(kind), 1e3 * seconds);
  }
  std::printf("\n");
}

// The GPU decoder's forward (Logits) and forward + input gradient at 128 and
// 256.
void CudaDecoderTimings(watergs::HiddenModel& model, bool tf32, int repeats) {
  using namespace watergs;
  std::unique_ptr<BitDecoder> gpu = MakeGpuHiddenDecoder(model, tf32);
  BitDecoder& decoder = *gpu;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (int size : {128, 256}) {
    ImageRGB image(size, size);
    for (float& v : image.data) v = unit(rng);
    std::vector<float> dlogits(model.config.num_bits, 0.01f);
    ImageRGB grad;
    // Each timed call gets a new image: the decoder skips the forward pass
    // for the image it last saw (a memcmp), which would be timed instead.
    const double forward = MedianSeconds(repeats, [&] {
      image.data[0] = unit(rng);
      decoder.Logits(image);
    });
    const double both = MedianSeconds(repeats, [&] {
      image.data[0] = unit(rng);  // defeat the forward cache
      decoder.InputGradient(image, dlogits, &grad);
    });
    const double macs = double(model.decoder->MacsPerPixel()) * size * size;
    std::printf(
        "cuda decoder %dx%d (%s): Logits %.2f ms (%.0f GFLOP/s), "
        "forward+input-gradient %.2f ms (%.0f GFLOP/s)\n",
        size, size, tf32 ? "TF32" : "float32", 1e3 * forward,
        2.0 * macs / forward * 1e-9, 1e3 * both, 4.0 * macs / both * 1e-9);
  }
}

// GPU decoder training steps (48 bits, 64 channels) at (crop, batch) under
// `kind`; GFLOP/s counts forward, backward-data and backward-filter of both
// networks as 3 forward passes.
void CudaTrainerTimings(int crop, int batch, watergs::NoiseKind kind, bool tf32,
                        int repeats) {
  using namespace watergs;
  HiddenConfig config;
  HiddenModel model(config, true, 2);
  NetworkAdam adam(model.AllParameters(), 1e-3f);
  std::unique_ptr<DeviceDecoderTrainer> trainer =
      MakeGpuDecoderTrainer(model, adam, tf32);
  ImageNoise noise;
  std::mt19937 rng(4);
  Tensor cover;
  std::vector<float> targets;
  RandomBatch(batch, crop, config.num_bits, &rng, &cover, &targets);
  const double seconds = MedianSeconds(repeats, [&] {
    trainer->Step(noise, kind, cover, targets, 0.7f, &rng);
    SynchronizeGpu();  // the Adam kernels are asynchronous
  });
  const double flops =
      6.0 *
      double(model.encoder->MacsPerPixel() + model.decoder->MacsPerPixel()) *
      crop * crop * batch;
  std::printf(
      "cuda training step (crop %d, batch %d, %s noise, %s): %.1f ms, %.2f "
      "steps/s, %.0f images/s, %.0f GFLOP/s\n",
      crop, batch, NoiseName(kind), tf32 ? "TF32" : "float32", 1e3 * seconds,
      1.0 / seconds, batch / seconds, flops / seconds * 1e-9);
}

// GPU timings of a HiDDeN decoder (the caller checked the GPU); the host
// part first.
int RunCuda(const std::string& weights, int repeats) {
  using namespace watergs;
  HostWorkPerStep(repeats);
  std::unique_ptr<HiddenModel> model = HiddenOf(weights);
  std::printf(
      "decoder_benchmark --device cuda: %s, hidden-model, %d bits, %d "
      "channels, %s\n",
      GpuDescription().c_str(), model->config.num_bits, model->config.channels,
      weights.empty() ? "random weights" : weights.c_str());
  for (bool tf32 : {false, true}) {
    CudaDecoderTimings(*model, tf32, repeats);
    CudaTrainerTimings(128, 8, NoiseKind::kIdentity, tf32, repeats);
    CudaTrainerTimings(256, 16, NoiseKind::kIdentity, tf32, repeats);
    CudaTrainerTimings(256, 16, NoiseKind::kJpeg, tf32, repeats);
  }
  return 0;
}

// A random-feature decoder read from `weights` (random weights when empty;
// a fresh network's projection is zero, which times the same).
std::unique_ptr<watergs::FeatureNet> FeatureNetOf(const std::string& weights) {
  using namespace watergs;
  if (weights.empty()) {
    return std::make_unique<FeatureNet>(FeatureDecoderConfig(), 1);
  }
  return FeatureNetFromFile(weights, ReadNetworkFile(weights));
}

// Logits, and forward + input gradient, of `decoder` at the crop sizes
// embed decodes and at a full 1280x800 frame; `label` starts each line.
void FeatureTimings(watergs::BitDecoder& decoder, double macs_per_pixel,
                    const char* label, int repeats) {
  using namespace watergs;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  // Crops, the demo's whole 240x180 frame, a 1280x800 frame.
  const int sizes[][2] = {{128, 128}, {256, 256}, {240, 180}, {1280, 800}};
  for (const auto& size : sizes) {
    ImageRGB image(size[0], size[1]);
    for (float& v : image.data) v = unit(rng);
    const std::vector<float> dlogits(decoder.NumBits(), 0.01f);
    ImageRGB grad;
    // A new image each call: the decoder skips the forward pass of the
    // image it last saw (a memcmp), which would be timed instead.
    const double forward = MedianSeconds(repeats, [&] {
      image.data[0] = unit(rng);
      decoder.Logits(image);
    });
    const double both = MedianSeconds(repeats, [&] {
      image.data[0] = unit(rng);
      decoder.InputGradient(image, dlogits, &grad);
    });
    const double macs = macs_per_pixel * double(size[0]) * size[1];
    std::printf(
        "%s %dx%d: Logits %.2f ms (%.1f GFLOP/s), forward+input-gradient "
        "%.2f ms (%.1f GFLOP/s)\n",
        label, size[0], size[1], 1e3 * forward, 2.0 * macs / forward * 1e-9,
        1e3 * both, 4.0 * macs / both * 1e-9);
  }
}

void PrintFeatureHeader(const watergs::FeatureNet& net,
                        const std::string& weights, const std::string& where) {
  const watergs::FeatureDecoderConfig& config = net.config();
  std::printf(
      "decoder_benchmark%s: feature-decoder, %d bits, %d channels, pool %d, "
      "kernel %d, %s\n",
      where.c_str(), config.num_bits, config.channels, config.pool,
      config.kernel, weights.empty() ? "random weights" : weights.c_str());
}

int RunFeatureCpu(const std::string& weights, int repeats) {
  using namespace watergs;
  std::unique_ptr<FeatureNet> net = FeatureNetOf(weights);
  PrintFeatureHeader(*net, weights,
                     " (" + std::to_string(Eigen::nbThreads()) + " threads)");
  const double macs = net->MacsPerPixel();
  FeatureDecoder decoder(std::move(net));
  FeatureTimings(decoder, macs, "feature decoder", repeats);
  return 0;
}

int RunFeatureCuda(const std::string& weights, int repeats) {
  using namespace watergs;
  std::unique_ptr<FeatureNet> net = FeatureNetOf(weights);
  PrintFeatureHeader(*net, weights, " --device cuda: " + GpuDescription());
  for (bool tf32 : {false, true}) {
    std::unique_ptr<BitDecoder> decoder = MakeGpuFeatureDecoder(*net, tf32);
    FeatureTimings(
        *decoder, net->MacsPerPixel(),
        tf32 ? "cuda feature decoder (TF32)" : "cuda feature decoder (float32)",
        repeats);
  }
  return 0;
}

// What the command line asks for.
struct Args {
  // cpu, cuda or auto, as typed.
  std::string device = "cpu";
  int repeats = 5;
  // Weights files; none: a random decoder of each kind.
  std::vector<std::string> weights;
};

constexpr char kUsage[] =
    "decoder_benchmark [--device cpu|cuda|auto] [--repeats N] "
    "[WEIGHTS.bin ...]";

// Strict: every word is a known option with its value or an existing file;
// anything else is a one-line error (thrown as watergs::Error).
Args ParseArgs(int argc, char** argv) {
  using watergs::Fail;
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    std::string value;
    const bool is_option = arg.rfind("--", 0) == 0;
    const size_t eq = arg.find('=');
    const std::string name = is_option ? arg.substr(0, eq) : "";
    if (is_option && name != "--device" && name != "--repeats") {
      Fail("unknown option '" + watergs::Printable(arg) + "'");
    }
    if (is_option) {
      if (eq != std::string::npos) {
        value = arg.substr(eq + 1);
      } else if (i + 1 < argc) {
        value = argv[++i];
      } else {
        Fail(name + " needs a value");
      }
    }
    if (name == "--device") {
      if (value != "cpu" && value != "cuda" && value != "auto") {
        Fail("--device: expected cpu, cuda or auto, got '" +
             watergs::Printable(value) + "'");
      }
      args.device = value;
    } else if (name == "--repeats") {
      size_t used = 0;
      int repeats = 0;
      try {
        repeats = std::stoi(value, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != value.size() || repeats < 1) {
        Fail("--repeats: expected a whole number >= 1, got '" +
             watergs::Printable(value) + "'");
      }
      args.repeats = repeats;
    } else if (!std::filesystem::is_regular_file(arg)) {
      Fail("'" + watergs::Printable(arg) +
           "' is not a weights file (the repeat count is --repeats N)");
    } else {
      args.weights.push_back(arg);
    }
  }
  return args;
}

// The kind of a weights file ("hidden-model", "feature-decoder", ...).
std::string KindOf(const std::string& weights) {
  return watergs::ReadNetworkFile(weights).kind;
}

int Run(const Args& args) {
  using namespace watergs;
  // --device cuda falls back to the CPU where there is no GPU (a benchmark
  // on a GPU-less machine still has CPU figures to give); auto as every
  // command's --device (ResolveDevice says the fallback on stderr).
  Device device = Device::kCpu;
  if (args.device == "cuda") {
    std::string why;
    if (CudaAvailable(&why)) {
      device = Device::kCuda;
    } else {
      std::printf("decoder_benchmark --device cuda: no GPU (%s): CPU timings\n",
                  why.c_str());
    }
  } else {
    device = ResolveDevice(args.device);
  }
  // (file, kind) pairs; no files: a random decoder of each kind.
  std::vector<std::pair<std::string, std::string>> decoders;
  for (const std::string& path : args.weights) {
    decoders.emplace_back(path, KindOf(path));
  }
  if (decoders.empty()) {
    decoders = {{"", "hidden-model"}, {"", kFeatureDecoderKind}};
  }
  for (const auto& [path, kind] : decoders) {
    if (kind == kFeatureDecoderKind) {
      if (device == Device::kCuda) {
        RunFeatureCuda(path, args.repeats);
      } else {
        RunFeatureCpu(path, args.repeats);
      }
    } else if (kind == "hidden-model" || kind == "hidden-checkpoint") {
      if (device == Device::kCuda) {
        RunCuda(path, args.repeats);
      } else {
        RunCpu(path, args.repeats);
      }
    } else {
      FailAt(path, "holds a '" + kind +
                       "', not a decoder (hidden-model or feature-decoder)");
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(ParseArgs(argc, argv));
  } catch (const watergs::Error& e) {
    std::fprintf(stderr, "decoder_benchmark: %s (usage: %s)\n", e.what(),
                 kUsage);
    return 2;
  }
}
