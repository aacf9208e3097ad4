// Tests of LPIPS-VGG: a weights file written in the documented format (random
// weights) loads, the distance matches a direct double-precision evaluation
// of the definition (plain loops, no im2col), is zero for identical images
// and symmetric; corrupted and truncated files are refused naming the file;
// the evaluation fills its LPIPS column with these distances.
#include "watermark/lpips.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/common/look_at.h"
#include "watermark/evaluation.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

// Standard CRC-32 (reflected, polynomial 0xEDB88320), one byte at a time
// through a table of the bitwise definition.
uint32_t Crc32(const std::string& bytes) {
  static const std::vector<uint32_t> table = [] {
    std::vector<uint32_t> t(256);
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t crc = i;
      for (int k = 0; k < 8; ++k)
        crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1)));
      t[i] = crc;
    }
    return t;
  }();
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char byte : bytes)
    crc = table[(crc ^ byte) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

struct RefTensor {
  std::string name;
  std::vector<int64_t> shape;
  std::vector<float> values;
};

const int kWidths[13] = {64,  64,  128, 128, 256, 256, 256,
                         512, 512, 512, 512, 512, 512};
const int kIndices[13] = {0, 2, 5, 7, 10, 12, 14, 17, 19, 21, 24, 26, 28};

// Random weights with variance-preserving scale, positive heads.
std::vector<RefTensor> RandomWeights(uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<RefTensor> t = {
      {"scaling.shift", {3}, {-0.03f, -0.088f, -0.188f}},
      {"scaling.scale", {3}, {0.458f, 0.448f, 0.45f}}};
  int in = 3;
  for (int k = 0; k < 13; ++k) {
    const int out = kWidths[k];
    const float bound = std::sqrt(6.f / (in * 9));
    std::uniform_real_distribution<float> u(-bound, bound);
    RefTensor w{"features." + std::to_string(kIndices[k]) + ".weight",
                {out, in, 3, 3},
                std::vector<float>(size_t(out) * in * 9)};
    for (float& v : w.values) v = u(rng);
    RefTensor b{"features." + std::to_string(kIndices[k]) + ".bias",
                {out},
                std::vector<float>(out)};
    for (float& v : b.values) v = 0.1f * u(rng);
    t.push_back(w);
    t.push_back(b);
    in = out;
  }
  const int taps[5] = {64, 128, 256, 512, 512};
  std::uniform_real_distribution<float> positive(0.f, 1.f);
  for (int l = 0; l < 5; ++l) {
    RefTensor h{"lin" + std::to_string(l) + ".weight",
                {1, taps[l], 1, 1},
                std::vector<float>(taps[l])};
    for (float& v : h.values) v = positive(rng);
    t.push_back(h);
  }
  return t;
}

std::string Serialize(const std::vector<RefTensor>& tensors) {
  std::string blob = "WGLPIPS1";
  const auto put = [&blob](const void* p, size_t n) {
    blob.append(static_cast<const char*>(p), n);
  };
  const uint32_t count = tensors.size();
  put(&count, 4);
  for (const RefTensor& t : tensors) {
    const uint32_t name_size = t.name.size(), ndim = t.shape.size();
    put(&name_size, 4);
    put(t.name.data(), name_size);
    put(&ndim, 4);
    put(t.shape.data(), ndim * 8);
    put(t.values.data(), t.values.size() * 4);
  }
  const uint32_t crc = Crc32(blob);
  put(&crc, 4);
  return blob;
}

// C x H x W feature maps in double.
struct Map {
  int c, h, w;
  std::vector<double> v;
  double& at(int ch, int y, int x) { return v[(size_t(ch) * h + y) * w + x]; }
};

Map ConvRelu(const Map& x, const RefTensor& weight, const RefTensor& bias) {
  const int out = int(weight.shape[0]);
  Map y{out, x.h, x.w, std::vector<double>(size_t(out) * x.h * x.w)};
  for (int o = 0; o < out; ++o)
    for (int py = 0; py < x.h; ++py)
      for (int px = 0; px < x.w; ++px) {
        double sum = bias.values[o];
        for (int i = 0; i < x.c; ++i)
          for (int ky = 0; ky < 3; ++ky)
            for (int kx = 0; kx < 3; ++kx) {
              const int sy = py + ky - 1, sx = px + kx - 1;
              if (sy < 0 || sy >= x.h || sx < 0 || sx >= x.w) continue;
              sum += weight.values[((size_t(o) * x.c + i) * 3 + ky) * 3 + kx] *
                     x.v[(size_t(i) * x.h + sy) * x.w + sx];
            }
        y.at(o, py, px) = std::max(sum, 0.0);
      }
  return y;
}

Map Pool(const Map& x) {
  Map y{x.c, x.h / 2, x.w / 2, {}};
  y.v.resize(size_t(y.c) * y.h * y.w);
  for (int c = 0; c < y.c; ++c)
    for (int py = 0; py < y.h; ++py)
      for (int px = 0; px < y.w; ++px) {
        double m = -1e300;
        for (int k = 0; k < 4; ++k)
          m = std::max(
              m,
              x.v[(size_t(c) * x.h + 2 * py + k / 2) * x.w + 2 * px + k % 2]);
        y.at(c, py, px) = m;
      }
  return y;
}

std::vector<Map> ReferenceTaps(const std::vector<RefTensor>& t,
                               const ImageRGB& image) {
  Map x{3, image.height, image.width, {}};
  x.v.resize(size_t(3) * image.height * image.width);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < image.height; ++y)
      for (int px = 0; px < image.width; ++px)
        x.at(c, y, px) =
            (2.0 * image.At(px, y)[c] - 1.0 - t[0].values[c]) / t[1].values[c];
  std::vector<Map> taps;
  const int blocks[5] = {2, 2, 3, 3, 3};
  int conv = 0;
  for (int b = 0; b < 5; ++b) {
    if (b > 0) x = Pool(x);
    for (int k = 0; k < blocks[b]; ++k, ++conv) {
      x = ConvRelu(x, t[2 + 2 * conv], t[3 + 2 * conv]);
    }
    Map n = x;
    for (int py = 0; py < n.h; ++py)
      for (int px = 0; px < n.w; ++px) {
        double sq = 0;
        for (int c = 0; c < n.c; ++c) sq += n.at(c, py, px) * n.at(c, py, px);
        for (int c = 0; c < n.c; ++c) n.at(c, py, px) /= std::sqrt(sq) + 1e-10;
      }
    taps.push_back(n);
  }
  return taps;
}

double ReferenceLpips(const std::vector<RefTensor>& t, const ImageRGB& a,
                      const ImageRGB& b) {
  const std::vector<Map> fa = ReferenceTaps(t, a), fb = ReferenceTaps(t, b);
  double total = 0;
  for (int l = 0; l < 5; ++l) {
    double sum = 0;
    for (int c = 0; c < fa[l].c; ++c)
      for (size_t i = 0; i < size_t(fa[l].h) * fa[l].w; ++i) {
        const double d = fa[l].v[c * fa[l].h * fa[l].w + i] -
                         fb[l].v[c * fb[l].h * fb[l].w + i];
        sum += t[28 + l].values[c] * d * d;
      }
    total += sum / (fa[l].h * fa[l].w);
  }
  return total;
}

ImageRGB RandomImage(int w, int h, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  ImageRGB image(w, h);
  for (float& v : image.data) v = u(rng);
  return image;
}

// One random weights file for all tests (60 MB: written once).
class LpipsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(
        std::filesystem::temp_directory_path() /
        ("watergs_lpips_test_" + std::to_string(::getpid())));
    std::filesystem::create_directories(*dir_);
    weights_ = new std::vector<RefTensor>(RandomWeights(5));
    blob_ = new std::string(Serialize(*weights_));
    path_ = new std::string((*dir_ / "lpips_vgg.bin").string());
    std::ofstream(*path_, std::ios::binary) << *blob_;
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
    delete weights_;
    delete blob_;
    delete path_;
  }
  static std::filesystem::path* dir_;
  static std::vector<RefTensor>* weights_;
  static std::string* blob_;
  static std::string* path_;
};
std::filesystem::path* LpipsTest::dir_ = nullptr;
std::vector<RefTensor>* LpipsTest::weights_ = nullptr;
std::string* LpipsTest::blob_ = nullptr;
std::string* LpipsTest::path_ = nullptr;

TEST(LpipsCrc, MatchesTheStandardCheckValue) {
  EXPECT_EQ(Crc32("123456789"), 0xCBF43926u);
}

TEST_F(LpipsTest, MatchesTheDefinitionEvaluatedDirectly) {
  auto lpips = Lpips::Load(*path_);
  // 18 x 17: taps of 18x17, 9x8, 4x4, 2x2, 1x1 (odd sizes exercise the floor).
  const ImageRGB a = RandomImage(18, 17, 1), b = RandomImage(18, 17, 2);
  const double expected = ReferenceLpips(*weights_, a, b);
  EXPECT_GT(expected, 0.0);
  const Lpips::Features fa = lpips->Extract(a), fb = lpips->Extract(b);
  EXPECT_NEAR(lpips->Distance(fa, fb), expected, 1e-4 * expected);
  EXPECT_EQ(lpips->Distance(fa, fa), 0.0);
  EXPECT_NEAR(lpips->Distance(fb, fa), lpips->Distance(fa, fb), 1e-12);
  EXPECT_THROW(lpips->Distance(RandomImage(15, 20, 3), RandomImage(15, 20, 4)),
               Error);
}

TEST_F(LpipsTest, RefusesCorruptedTruncatedAndIncompleteFiles) {
  std::string flipped = *blob_;
  flipped[100] ^= 1;
  const std::string corrupted = (*dir_ / "corrupted.bin").string();
  std::ofstream(corrupted, std::ios::binary) << flipped;
  const std::string truncated = (*dir_ / "truncated.bin").string();
  std::ofstream(truncated, std::ios::binary) << blob_->substr(0, 5000);
  // Valid CRC, but only the input scaling.
  const std::vector<RefTensor> scaling(weights_->begin(),
                                       weights_->begin() + 2);
  const std::string incomplete = (*dir_ / "incomplete.bin").string();
  std::ofstream(incomplete, std::ios::binary) << Serialize(scaling);
  for (const std::string& path :
       {corrupted, truncated, incomplete, (*dir_ / "absent.bin").string()}) {
    try {
      Lpips::Load(path);
      ADD_FAILURE() << path << " loaded";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
          << e.what();
    }
  }
}

// Tensor headers that claim more than the file holds: refused from the
// header, before any allocation (a 1 GB tensor in a 60-byte file, four
// dimensions whose product overflows int64), and names that would break the
// one-line error.
TEST_F(LpipsTest, RefusesHeadersThatClaimMoreThanTheFileHolds) {
  struct Case {
    std::string label;
    RefTensor tensor;
    std::string problem;
  };
  const std::vector<Case> cases = {
      {"gigabyte",
       {"scaling.shift", {1 << 14, 1 << 14}, {1.f, 2.f}},
       "truncated"},
      {"overflow",
       {"scaling.shift", {1 << 24, 1 << 24, 1 << 24, 1 << 24}, {1.f}},
       "too large"},
      {"newline", {"scaling\nshift", {1}, {1.f}}, "control character"}};
  for (const auto& [label, tensor, problem] : cases) {
    const std::string path = (*dir_ / (label + ".bin")).string();
    std::ofstream(path, std::ios::binary) << Serialize({tensor});
    try {
      Lpips::Load(path);
      ADD_FAILURE() << label << " loaded";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(path, 0), 0u) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << label;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
    }
  }
}

ImageRGB RenderClamped(const GaussianModel& model, const RenderCamera& cam) {
  ImageRGB image;
  MakeCpuRasterizer()->Forward(model, cam, RenderOptions{}, &image, nullptr);
  for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
  return image;
}

TEST_F(LpipsTest, EvaluationFillsTheLpipsColumn) {
  auto lpips = Lpips::Load(*path_);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel raw;
  raw.sh_degree = 0;
  raw.Resize(200);
  for (float& v : raw.means) v = u(rng);
  for (float& v : raw.log_scales) v = -2.5f + 0.3f * u(rng);
  for (float& v : raw.quats) v = u(rng);
  for (float& v : raw.opacity_logits) v = 2.f * u(rng);
  for (float& v : raw.sh_dc) v = u(rng);
  GaussianModel wm = raw;
  for (float& v : wm.sh_dc) v += 0.1f;
  InMemoryViews views;
  std::vector<RenderCamera> cameras = {
      LookAtOrigin(Eigen::Vector3d(3, 1, 1), 32, 24),
      LookAtOrigin(Eigen::Vector3d(-2, 2.5, 0.5), 32, 24)};
  for (size_t k = 0; k < cameras.size(); ++k) {
    views.Add("v" + std::to_string(k), cameras[k],
              RenderClamped(raw, cameras[k]));
  }
  HiddenConfig config;
  config.num_bits = 16;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 2;
  HiddenModel net(config, false, 3);
  Decoder decoder(&net);
  EvaluationOptions options;
  options.lpips = lpips.get();
  options.model_attacks = {ParseModelAttack("identity")};
  options.image_attacks = {};
  const EvaluationReport report =
      EvaluateWatermark(*MakeCpuRasterizer(), raw, wm, views, {0, 1}, decoder,
                        ParseMessage("hex:a5c3", 16), options);
  EXPECT_EQ(report.lpips_note, "");
  ASSERT_TRUE(report.vs_raw.mean.has_lpips);
  double expected = 0;
  for (const RenderCamera& camera : cameras) {
    expected += 0.5 * lpips->Distance(RenderClamped(wm, camera),
                                      RenderClamped(raw, camera));
  }
  EXPECT_GT(expected, 0.0);
  EXPECT_NEAR(report.vs_raw.mean.lpips, expected, 1e-9 * expected);
  // The ground truth is the raw render itself.
  EXPECT_EQ(report.raw_vs_ground_truth.mean.lpips, 0.0);
  EXPECT_NEAR(report.vs_ground_truth.mean.lpips, expected, 1e-9 * expected);
  EXPECT_TRUE(std::isinf(report.raw_vs_ground_truth.mean.psnr));
  ASSERT_EQ(report.robustness.size(), 2u);
}

TEST(MaxPool2x2, TakesTheBlockMaximumAndDropsOddEdges) {
  Tensor x(1, 2, 3, 5);
  for (size_t i = 0; i < x.size(); ++i) x.data[i] = float((i * 7) % 11);
  Tensor y;
  MaxPool2x2Forward(x, &y);
  ASSERT_EQ(y.h, 1);
  ASSERT_EQ(y.w, 2);
  for (int c = 0; c < 2; ++c)
    for (int ox = 0; ox < 2; ++ox) {
      const float* p = x.Plane(0, c);
      const float m = std::max(
          {p[2 * ox], p[2 * ox + 1], p[5 + 2 * ox], p[5 + 2 * ox + 1]});
      EXPECT_EQ(y.Plane(0, c)[ox], m);
    }
}

}  // namespace
}  // namespace watergs
