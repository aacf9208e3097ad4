// Tests of the decoder interface (watermark/bit_decoder.h): LoadBitDecoder
// gives the CPU Decoder with Decoder::Load's errors, refuses the GPU in one
// line where there is none, and on a GPU loads a CudaDecoder that reads the
// same logits and, through ExtractWatermark, the same bits as the CPU one.
#include "watermark/bit_decoder.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"
#include "tests/common/look_at.h"
#include "watermark/decoder.h"
#include "watermark/extractor.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

HiddenConfig TinyConfig() {
  HiddenConfig config;
  config.num_bits = 16;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 2;
  return config;
}

// A folder of this test process's files, removed with it.
class TempFolder {
 public:
  TempFolder()
      : path_(std::filesystem::temp_directory_path() /
              ("watergs_bit_decoder_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~TempFolder() { std::filesystem::remove_all(path_); }
  std::string File(const std::string& name) const {
    return (path_ / name).string();
  }

 private:
  std::filesystem::path path_;
};

// A smooth image with some texture, values in [0, 1].
ImageRGB TestImage(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-0.1f, 0.1f);
  ImageRGB image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float base = 0.5f + 0.3f * std::sin(0.3f * x + 0.2f * y + c);
        image.data[3 * (y * width + x) + c] =
            std::clamp(base + noise(rng), 0.f, 1.f);
      }
    }
  }
  return image;
}

// The message of the Error `load` throws ("(no error)" when none).
std::string ErrorOf(const std::function<void()>& load) {
  try {
    load();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// A missing file, a truncated copy of `good` and `good` read as 32 bits:
// LoadBitDecoder on `device` fails as Decoder::Load does.
void ExpectDecoderLoadErrors(const TempFolder& folder, const std::string& good,
                             Device device) {
  const std::string truncated = folder.File("truncated.bin");
  {
    std::ifstream in(good, std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
    ASSERT_GT(bytes.size(), 100u);
    std::ofstream out(truncated, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size() - 100));
  }
  const std::string missing = folder.File("missing.bin");
  const std::vector<std::pair<std::string, int>> cases = {
      {missing, 0}, {truncated, 0}, {good, 32}};
  for (const std::pair<std::string, int>& bad : cases) {
    const std::string& path = bad.first;
    const int bits = bad.second;
    const std::string expected = ErrorOf([&] { Decoder::Load(path, bits); });
    ASSERT_NE(expected, "(no error)") << path;
    EXPECT_EQ(ErrorOf([&] { LoadBitDecoder(path, device, bits); }), expected);
  }
}

TEST(LoadBitDecoder, CpuReadsWhatTheSavedDecoderReads) {
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 7);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  const std::unique_ptr<BitDecoder> loaded =
      LoadBitDecoder(path, Device::kCpu, 16);
  Decoder reference(&net);
  EXPECT_EQ(loaded->NumBits(), 16);
  const ImageRGB image = TestImage(20, 14, 3);
  // The file holds the float weights as they are: the same numbers come out.
  EXPECT_EQ(loaded->Logits(image), reference.Logits(image));
  std::vector<float> dlogits(16);
  for (int i = 0; i < 16; ++i) dlogits[i] = 0.1f * (i - 7.5f);
  ImageRGB dimage;
  loaded->InputGradient(image, dlogits, &dimage);
  EXPECT_EQ(dimage.data, reference.InputGradient(image, dlogits).data);
}

// The decoder keeps its last forward pass for InputGradient of the same
// image; any other image, of the same size or not, or the same buffer with one
// value changed, must get a fresh forward pass: each answer equals that of a
// decoder that never saw another image (a separate copy of the weights, so
// that no network state is shared).
TEST(LoadBitDecoder, CacheMissesGiveAFreshDecodersAnswers) {
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 7);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  std::vector<float> dlogits(16);
  for (int i = 0; i < 16; ++i) dlogits[i] = 0.1f * (i - 7.5f);
  auto fresh_logits = [&](const ImageRGB& image) {
    return Decoder::Load(path, 16).Logits(image);
  };
  auto fresh_gradient = [&](const ImageRGB& image) {
    return Decoder::Load(path, 16).InputGradient(image, dlogits).data;
  };
  const ImageRGB a = TestImage(20, 14, 3), b = TestImage(20, 14, 4),
                 c = TestImage(17, 11, 5);
  // The cases can tell a cache hit from a miss.
  ASSERT_NE(fresh_gradient(a), fresh_gradient(b));
  ASSERT_NE(fresh_logits(a), fresh_logits(b));

  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(path, Device::kCpu, 16);
  ImageRGB dimage;
  EXPECT_EQ(decoder->Logits(a), fresh_logits(a));
  // InputGradient(B) after Logits(A), B of the same size.
  decoder->InputGradient(b, dlogits, &dimage);
  EXPECT_EQ(dimage.data, fresh_gradient(b)) << "gradient of A's pass";
  EXPECT_EQ(decoder->Logits(b), fresh_logits(b));
  // Another size, then back to A.
  decoder->InputGradient(c, dlogits, &dimage);
  EXPECT_EQ(dimage.width, c.width);
  EXPECT_EQ(dimage.data, fresh_gradient(c));
  EXPECT_EQ(decoder->Logits(a), fresh_logits(a));
  decoder->InputGradient(a, dlogits, &dimage);
  EXPECT_EQ(dimage.data, fresh_gradient(a));
  // A render into the same buffer that changes one value.
  ImageRGB edited = a;
  edited.data[3 * (7 * 20 + 9) + 1] += 0.25f;
  ASSERT_NE(fresh_logits(edited), fresh_logits(a));
  EXPECT_EQ(decoder->Logits(edited), fresh_logits(edited));
  decoder->InputGradient(edited, dlogits, &dimage);
  EXPECT_EQ(dimage.data, fresh_gradient(edited));
}

TEST(LoadBitDecoder, CpuFailsAsDecoderLoadDoes) {
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 7);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  ExpectDecoderLoadErrors(folder, path, Device::kCpu);
}

TEST(LoadBitDecoder, CudaWithoutAGpuIsAOneLineError) {
  std::string why;
  if (CudaAvailable(&why)) {
    GTEST_SKIP() << "a GPU is visible: LoadBitDecoderCuda covers it";
  }
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 7);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  const std::string message =
      ErrorOf([&] { LoadBitDecoder(path, Device::kCuda); });
  EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
  EXPECT_NE(message.find(why), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

// GPU decoders sum their FP32 convolutions in another order than the CPU's
// (no TF32): logits agree to 1e-3 of the largest |logit|, the tolerance of
// tests/watermark/cuda_decoder_test.cc.
constexpr double kLogitTolerance = 1e-3;

double MaxAbs(const std::vector<float>& values) {
  double scale = 0;
  for (float v : values) scale = std::max(scale, double(std::abs(v)));
  return scale;
}

void ExpectLogitsClose(const std::vector<float>& gpu,
                       const std::vector<float>& cpu, const std::string& what) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  const double tolerance = kLogitTolerance * MaxAbs(cpu);
  for (size_t i = 0; i < cpu.size(); ++i) {
    EXPECT_NEAR(gpu[i], cpu[i], tolerance) << what << " logit " << i;
  }
}

TEST(LoadBitDecoderCuda, LoadsTheFileAsTheCpuDecoderDoes) {
  WATERGS_REQUIRE_CUDA();
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 7);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  const std::unique_ptr<BitDecoder> gpu =
      LoadBitDecoder(path, Device::kCuda, 16);
  Decoder cpu(&net);
  EXPECT_EQ(gpu->NumBits(), 16);
  const ImageRGB image = TestImage(20, 14, 3);
  ExpectLogitsClose(gpu->Logits(image), cpu.Logits(image), "logits");
  ExpectDecoderLoadErrors(folder, path, Device::kCuda);
}

// A small scene seen from `n` cameras around it.
struct ExtractScene {
  GaussianModel model;
  std::vector<RenderCamera> cameras;
  std::vector<std::string> names;
};

ExtractScene MakeExtractScene(int n, int width, int height) {
  ExtractScene s;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  s.model.sh_degree = 0;
  s.model.Resize(60);
  for (int i = 0; i < 60; ++i) {
    for (int a = 0; a < 3; ++a) {
      s.model.means[3 * i + a] = 0.8f * u(rng);
      s.model.log_scales[3 * i + a] = std::log(0.12f * (1.2f + 0.5f * u(rng)));
      s.model.sh_dc[3 * i + a] = 1.2f * u(rng);
    }
    s.model.quats[4 * i] = 1;
    s.model.opacity_logits[i] = 1.0f + u(rng);
  }
  for (int v = 0; v < n; ++v) {
    const double a = 2 * M_PI * v / n;
    s.cameras.push_back(LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), width, height));
    s.names.push_back("v" + std::to_string(v));
  }
  return s;
}

// `gpu` reads `cpu`'s per-view logits within kLogitTolerance and the same
// recovered bits wherever the CPU's mean logit is clear of that tolerance.
void ExpectExtractionsAgree(const ExtractionResult& gpu,
                            const ExtractionResult& cpu,
                            const std::string& what) {
  ASSERT_EQ(gpu.views.size(), cpu.views.size()) << what;
  for (size_t v = 0; v < cpu.views.size(); ++v) {
    ExpectLogitsClose(gpu.views[v].logits, cpu.views[v].logits,
                      what + " view " + std::to_string(v));
  }
  ExpectLogitsClose(gpu.mean_logits, cpu.mean_logits, what + " mean");
  const double clear = kLogitTolerance * MaxAbs(cpu.mean_logits);
  int compared = 0;
  for (size_t i = 0; i < cpu.recovered.size(); ++i) {
    if (std::abs(cpu.mean_logits[i]) <= clear) continue;
    EXPECT_EQ(gpu.recovered[i], cpu.recovered[i]) << what << " bit " << i;
    ++compared;
  }
  EXPECT_GT(compared, int(cpu.recovered.size()) / 2) << what;
}

TEST(LoadBitDecoderCuda, ExtractionReadsTheCpuDecodersBits) {
  WATERGS_REQUIRE_CUDA();
  TempFolder folder;
  HiddenModel net(TinyConfig(), false, 21);
  const std::string path = folder.File("decoder.bin");
  SaveHiddenModel(path, net, false);
  const ExtractScene s = MakeExtractScene(4, 48, 32);
  Bits expected(16);
  for (int i = 0; i < 16; ++i) expected[i] = (i * 7) % 3 == 0;
  const std::unique_ptr<BitDecoder> cpu_decoder =
      LoadBitDecoder(path, Device::kCpu);
  const std::unique_ptr<BitDecoder> gpu_decoder =
      LoadBitDecoder(path, Device::kCuda);
  const auto extract = [&](Rasterizer& rasterizer, BitDecoder& decoder) {
    return ExtractWatermark(rasterizer, s.model, s.cameras, s.names, decoder,
                            &expected, {0, 0, 0}, VerificationThresholds{});
  };
  const auto cpu_rasterizer = MakeRasterizer(Device::kCpu);
  const auto gpu_rasterizer = MakeRasterizer(Device::kCuda);
  const ExtractionResult reference = extract(*cpu_rasterizer, *cpu_decoder);
  // The decoder alone on the GPU, then what `extract --device cuda` runs.
  ExpectExtractionsAgree(extract(*cpu_rasterizer, *gpu_decoder), reference,
                         "GPU decoder");
  ExpectExtractionsAgree(extract(*gpu_rasterizer, *gpu_decoder), reference,
                         "GPU rasterizer and decoder");
}

}  // namespace
}  // namespace watergs
