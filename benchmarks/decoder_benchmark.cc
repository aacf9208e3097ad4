// Decoder benchmark: frozen-decoder forward + input-gradient time at 128x128
// and 256x256 with its GFLOP/s; the 64->64 3x3 convolution layer against
// Eigen's own float matrix product of the same shape, measured in the same
// run; and training throughput (images/s) of the default configuration
// (crop 128, batch 8, identity noise, 48 bits). Medians of repeated runs.
//
// Usage: decoder_benchmark [weights.bin] [repeats=5]
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "benchmarks/benchmark_util.h"
#include "watermark/decoder.h"
#include "watermark/decoder_training.h"

namespace {

using watergs::bench::MedianSeconds;

using Clock = std::chrono::steady_clock;

}  // namespace

int main(int argc, char** argv) {
  using namespace watergs;
  const std::string weights = argc > 1 ? argv[1] : "";
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  HiddenConfig config;
  std::unique_ptr<HiddenModel> model =
      weights.empty() ? std::make_unique<HiddenModel>(config, true, 1)
                      : LoadHiddenModel(weights, true);
  std::printf("decoder_benchmark: %d bits, %d channels, %s, %d threads max\n",
              model->config.num_bits, model->config.channels,
              weights.empty() ? "random weights" : weights.c_str(),
              Eigen::nbThreads());

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
