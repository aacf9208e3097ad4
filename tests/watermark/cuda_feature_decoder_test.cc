// Parity of the GPU random-feature decoder (watermark/cuda/
// cuda_feature_decoder.h) with the CPU one (FeatureDecoder): logits and
// input gradients on small random networks of several pool sizes and image
// sizes (with and without a border the pooling drops), the patch entry
// points the device-resident embedding step uses, the shipped decoder
// loaded by LoadBitDecoder, and the embedder taking the device-resident
// step with it. GPU tests skip without a GPU.
//
// Tolerances, relative to the largest |cpu| value compared: 1e-4 for the
// logits and input gradients (one cuDNN convolution, ~1e-5 relative with
// its Winograd/FFT algorithms (cuda_nn_test.cc), and double-summed global
// pooling on both sides; the projection is one cuBLAS GEMV); the patch
// entry points equal the whole-image ones on the GPU bit for bit (the
// same kernels on the same values).
#ifdef WATERGS_WITH_CUDA

#include "watermark/cuda/cuda_feature_decoder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/cuda/device_buffer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"
#include "watermark/bit_decoder.h"
#include "watermark/feature_decoder.h"

namespace watergs {
namespace {

constexpr double kTolerance = 1e-4;

const std::string kShippedDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

double MaxAbs(const std::vector<float>& values) {
  double scale = 0.0;
  for (float v : values) scale = std::max(scale, double(std::abs(v)));
  return scale;
}

void ExpectClose(const std::vector<float>& gpu, const std::vector<float>& cpu,
                 const std::string& what) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  const double scale = MaxAbs(cpu);
  ASSERT_GT(scale, 0) << what << ": nothing to compare";
  double worst = 0.0;
  size_t at = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    ASSERT_TRUE(std::isfinite(gpu[i])) << what << " [" << i << "]";
    const double d = std::abs(double(gpu[i]) - cpu[i]);
    if (d > worst) worst = d, at = i;
  }
  EXPECT_LE(worst, kTolerance * scale)
      << what << ": element " << at << " gpu " << gpu[at] << " cpu " << cpu[at]
      << " (scale " << scale << ")";
}

// A FeatureNet with a random projection (a fresh one's is zero).
std::unique_ptr<FeatureNet> RandomNet(int pool, uint32_t seed, int kernel = 3) {
  FeatureDecoderConfig config;
  config.num_bits = 16;
  config.channels = 96;
  config.pool = pool;
  config.kernel = kernel;
  auto net = std::make_unique<FeatureNet>(config, seed);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  for (float& w : net->linear.weight.value) w = normal(rng);
  for (float& b : net->linear.bias.value) b = 0.1f * normal(rng);
  return net;
}

ImageRGB TestImage(int w, int h, std::mt19937* rng) {
  ImageRGB image(w, h);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (float& v : image.data) v = unit(*rng);
  return image;
}

std::vector<float> RandomVector(size_t n, std::mt19937* rng) {
  std::normal_distribution<float> normal(0.f, 1.f);
  std::vector<float> v(n);
  for (float& x : v) x = normal(*rng);
  return v;
}

// Pool sizes 1, 2 and 4 (the shipped one) with the shipped 3x3 kernel, and
// 1x1 and 5x5 kernels (the im2col rows and their zero padding); images from
// the minimum (one pooled pixel) to ones whose width and height are not
// multiples of the pool (the CPU drops that border: its gradient must be
// exactly 0).
TEST(CudaFeatureDecoder, LogitsAndInputGradientMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(5);
  const int pool_kernel[][2] = {{1, 3}, {2, 3}, {4, 3}, {2, 1}, {2, 5}};
  for (const auto& [pool, kernel] : pool_kernel) {
    std::unique_ptr<FeatureNet> cpu_net =
        RandomNet(pool, 11 + pool + kernel, kernel);
    CudaFeatureDecoder gpu(*cpu_net);
    FeatureDecoder cpu(std::move(cpu_net));
    ASSERT_EQ(gpu.NumBits(), 16);
    const int sizes[][2] = {{pool, pool}, {32, 32}, {37, 29}, {70, 41}};
    for (const auto& size : sizes) {
      const std::string what =
          "pool " + std::to_string(pool) + " kernel " + std::to_string(kernel) +
          " " + std::to_string(size[0]) + "x" + std::to_string(size[1]);
      const ImageRGB image = TestImage(size[0], size[1], &rng);
      ExpectClose(gpu.Logits(image), cpu.Logits(image), what + " logits");
      const std::vector<float> dlogits = RandomVector(16, &rng);
      ImageRGB g_gpu, g_cpu;
      gpu.InputGradient(image, dlogits, &g_gpu);
      cpu.InputGradient(image, dlogits, &g_cpu);
      ASSERT_EQ(g_gpu.width, image.width);
      ASSERT_EQ(g_gpu.height, image.height);
      ExpectClose(g_gpu.data, g_cpu.data, what + " input gradient");
      for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
          if (x < image.width / pool * pool && y < image.height / pool * pool)
            continue;
          for (int c = 0; c < 3; ++c) {
            ASSERT_EQ(g_gpu.At(x, y)[c], 0.f)
                << what << " border " << x << "," << y;
          }
        }
      }
    }
  }
}

// The patch of a wider device image decodes as the cropped image does, and
// its input gradient is added into exactly that rect (other values kept);
// a gradient for another patch, or a rect outside the image, is refused.
TEST(CudaFeatureDecoder, PatchOfAWiderImageEqualsTheCroppedImage) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(47);
  std::unique_ptr<FeatureNet> net = RandomNet(4, 3);
  CudaFeatureDecoder gpu(*net);
  const ImageRGB image = TestImage(40, 28, &rng);
  const PixelRect rect{13, 6, 17, 16};
  ImageRGB cropped(rect.width, rect.height);
  for (int y = 0; y < rect.height; ++y)
    for (int x = 0; x < rect.width; ++x)
      for (int c = 0; c < 3; ++c)
        cropped.At(x, y)[c] = image.At(rect.x0 + x, rect.y0 + y)[c];
  const std::vector<float> dlogits = RandomVector(16, &rng);
  const std::vector<float> logits = gpu.Logits(cropped);
  ImageRGB dcropped;
  gpu.InputGradient(cropped, dlogits, &dcropped);

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
                                               image.width, {0, 0, 17, 16}),
               Error);
  EXPECT_THROW(
      gpu.LogitsDevicePatch(image_gpu.data(), image.width, {30, 0, 17, 16}),
      Error);
}

// An input smaller than the pooling, and a wrong count of logit gradients,
// are one-line errors (the CPU decoder's message for the first).
TEST(CudaFeatureDecoder, BadInputsAreOneLineErrors) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(9);
  std::unique_ptr<FeatureNet> net = RandomNet(4, 3);
  CudaFeatureDecoder gpu(*net);
  FeatureDecoder cpu(std::move(net));
  const ImageRGB small = TestImage(3, 8, &rng);
  std::string gpu_error, cpu_error;
  try {
    gpu.Logits(small);
  } catch (const Error& e) {
    gpu_error = e.what();
  }
  try {
    cpu.Logits(small);
  } catch (const Error& e) {
    cpu_error = e.what();
  }
  EXPECT_NE(gpu_error, "");
  EXPECT_EQ(gpu_error, cpu_error);
  EXPECT_EQ(gpu_error.find('\n'), std::string::npos);
  ImageRGB grad;
  EXPECT_THROW(gpu.InputGradient(TestImage(8, 8, &rng), {1.f, 2.f}, &grad),
               Error);
}

// What `embed/extract --device cuda` load for the shipped decoder: the CUDA
// twin, reading the CPU decoder's logits and input gradient on a photo-like
// 160x120 image.
TEST(CudaFeatureDecoder, LoadBitDecoderGivesTheShippedDecodersTwin) {
  WATERGS_REQUIRE_CUDA();
  const std::unique_ptr<BitDecoder> gpu =
      LoadBitDecoder(kShippedDecoder, Device::kCuda, 48);
  const std::unique_ptr<BitDecoder> cpu =
      LoadBitDecoder(kShippedDecoder, Device::kCpu, 48);
  ASSERT_NE(dynamic_cast<CudaFeatureDecoder*>(gpu.get()), nullptr);
  std::mt19937 rng(13);
  ImageRGB image(160, 120);
  // Smooth content with some noise, as photos have.
  std::uniform_real_distribution<float> noise(-0.05f, 0.05f);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < 3; ++c)
        image.At(x, y)[c] = std::clamp(
            0.5f + 0.3f * std::sin(0.07f * x + c) * std::cos(0.05f * y) +
                noise(rng),
            0.f, 1.f);
  ExpectClose(gpu->Logits(image), cpu->Logits(image), "shipped logits");
  const std::vector<float> dlogits = RandomVector(48, &rng);
  ImageRGB g_gpu, g_cpu;
  gpu->InputGradient(image, dlogits, &g_gpu);
  cpu->InputGradient(image, dlogits, &g_cpu);
  ExpectClose(g_gpu.data, g_cpu.data, "shipped input gradient");
}

}  // namespace
}  // namespace watergs

#endif  // WATERGS_WITH_CUDA
