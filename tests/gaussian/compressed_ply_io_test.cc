// Tests of the PlayCanvas compressed PLY reader and writer: values of a
// hand-built file (11-10-11 position and scale words, the 2-10-10-10
// rotation word, 8-8-8-8 colour with and without chunk colour ranges, uchar
// SH), round-trip error bounds from each chunk's ranges, Morton order, and
// one-line refusals of truncated, padded and malformed files.
#include "gaussian/formats/compressed_ply_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "tests/common/refusal.h"

namespace watergs {
namespace {

constexpr double kShC0 = 0.28209479177387814;

void PutF32(float f, std::string* out) {
  char b[4];
  std::memcpy(b, &f, 4);
  out->append(b, 4);
}

void PutU32(uint32_t v, std::string* out) {
  for (int k = 0; k < 4; ++k) out->push_back(char(v >> (8 * k)));
}

GaussianModel Decode(const std::string& bytes) {
  return DecodeCompressedPly("test.compressed.ply",
                             reinterpret_cast<const uint8_t*>(bytes.data()),
                             bytes.size());
}

// The one-line error for `bytes` (tests/common/refusal.h).
std::string Refusal(const std::string& bytes) {
  return testing::Refusal("test.compressed.ply", [&] { Decode(bytes); });
}

std::string Replace(std::string text, const std::string& from,
                    const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// A file of 2 Gaussians, SH degree 1, with or without chunk colour ranges.
std::string HandBuilt(bool colour_ranges) {
  std::string h =
      "ply\nformat binary_little_endian 1.0\ncomment hand-built\n"
      "element chunk 1\n";
  const char* names[] = {
      "min_x",       "min_y",       "min_z",       "max_x",       "max_y",
      "max_z",       "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x",
      "max_scale_y", "max_scale_z", "min_r",       "min_g",       "min_b",
      "max_r",       "max_g",       "max_b"};
  const int num_chunk = colour_ranges ? 18 : 12;
  for (int p = 0; p < num_chunk; ++p) {
    h += std::string("property float ") + names[p] + "\n";
  }
  h += "element vertex 2\nproperty uint packed_position\n"
       "property uint packed_rotation\nproperty uint packed_scale\n"
       "property uint packed_color\nelement sh 2\n";
  for (int j = 0; j < 9; ++j) {
    h += "property uchar f_rest_" + std::to_string(j) + "\n";
  }
  h += "end_header\n";
  const float chunk[] = {0,  -1, 2,  2047, 1,   4,   -5,   -5,  -5,
                         -1, -1, -1, 0.2f, 0.f, 0.f, 0.6f, 1.f, 1.f};
  for (int p = 0; p < num_chunk; ++p) PutF32(chunk[p], &h);
  // Gaussian 0: x 1000 of 2047, y 1023 of 1023, z 0; scales 0, 511, 2047;
  // rotation: rot_1 largest, rot_0 767, rot_2 256, rot_3 512 (of 1023);
  // colour r 255 g 0 b 128, alpha 0.
  PutU32(1000u << 21 | 1023u << 11 | 0u, &h);
  PutU32(1u << 30 | 767u << 20 | 256u << 10 | 512u, &h);
  PutU32(0u << 21 | 511u << 11 | 2047u, &h);
  PutU32(255u << 24 | 0u << 16 | 128u << 8 | 0u, &h);
  // Gaussian 1: x 2047, y 0, z 2047; rot_0 largest, others at 0.5 (zero);
  // colour 64 64 64, alpha 255.
  PutU32(2047u << 21 | 0u << 11 | 2047u, &h);
  PutU32(0u << 30 | 511u << 20 | 511u << 10 | 511u, &h);
  PutU32(2047u << 21 | 1023u << 11 | 0u, &h);
  PutU32(64u << 24 | 64u << 16 | 64u << 8 | 255u, &h);
  const uint8_t sh0[] = {0, 255, 128, 64, 128, 128, 128, 128, 128};
  h.append(reinterpret_cast<const char*>(sh0), 9);
  h.append(9, char(200));
  return h;
}

TEST(CompressedPlyIo, DecodesHandBuiltValues) {
  const GaussianModel m = Decode(HandBuilt(false));
  ASSERT_EQ(m.size(), 2u);
  ASSERT_EQ(m.sh_degree, 1);
  EXPECT_NEAR(m.means[0], 1000.0, 1e-3);
  EXPECT_NEAR(m.means[1], 1.0, 1e-6);
  EXPECT_NEAR(m.means[2], 2.0, 1e-6);
  EXPECT_NEAR(m.means[3], 2047.0, 1e-3);
  EXPECT_NEAR(m.means[4], -1.0, 1e-6);
  EXPECT_NEAR(m.means[5], 4.0, 1e-6);
  EXPECT_NEAR(m.log_scales[0], -5.0, 1e-6);
  EXPECT_NEAR(m.log_scales[1], -5.0 + 4.0 * 511 / 1023, 1e-5);
  EXPECT_NEAR(m.log_scales[2], -1.0, 1e-6);
  // Without chunk colour ranges the bytes are the colour itself.
  EXPECT_NEAR(m.sh_dc[0], 0.5 / kShC0, 1e-5);
  EXPECT_NEAR(m.sh_dc[1], -0.5 / kShC0, 1e-5);
  EXPECT_NEAR(m.sh_dc[2], (128 / 255.0 - 0.5) / kShC0, 1e-5);
  // Alpha 0 and 255 decode to -+kOpacityLogitLimit, not -+Inf.
  EXPECT_EQ(m.opacity_logits[0], -kOpacityLogitLimit);
  EXPECT_EQ(m.opacity_logits[1], kOpacityLogitLimit);
  const double a = (767 / 1023.0 - 0.5) * std::sqrt(2.0);
  const double b = (256 / 1023.0 - 0.5) * std::sqrt(2.0);
  const double c = (512 / 1023.0 - 0.5) * std::sqrt(2.0);
  const double largest = std::sqrt(1 - a * a - b * b - c * c);
  const double q0[] = {a, largest, b, c};  // rot_0..3 = w x y z
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(m.quats[k], q0[k], 1e-6) << k;
  EXPECT_NEAR(m.quats[4], 1.0, 1e-5);
  // f_rest_j is channel-major (3 coefficients a channel); the model keeps
  // coefficient-major rgb: f_rest_1 (red, coefficient 1) is sh_rest[3],
  // f_rest_3 (green, coefficient 0) is sh_rest[1].
  EXPECT_FLOAT_EQ(m.sh_rest[0], -4.f);  // byte 0
  EXPECT_FLOAT_EQ(m.sh_rest[3], 4.f);   // byte 255
  EXPECT_FLOAT_EQ(m.sh_rest[6], float((128.5 / 256 - 0.5) * 8));
  EXPECT_FLOAT_EQ(m.sh_rest[1], float((64.5 / 256 - 0.5) * 8));
  EXPECT_FLOAT_EQ(m.sh_rest[9], float((200.5 / 256 - 0.5) * 8));
}

TEST(CompressedPlyIo, ColourRangesScaleTheColourBytes) {
  const GaussianModel m = Decode(HandBuilt(true));
  EXPECT_NEAR(m.sh_dc[0], (0.6 - 0.5) / kShC0, 1e-5);  // r 255 -> max_r
  EXPECT_NEAR(m.sh_dc[1], (0.0 - 0.5) / kShC0, 1e-5);  // g 0 -> min_g
  EXPECT_NEAR(m.sh_dc[3], (0.2 + 0.4 * 64 / 255.0 - 0.5) / kShC0, 1e-5);
}

GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (float& v : m.means) v = 20.f * u(rng);
  for (float& v : m.log_scales) v = -5.f + 3.f * u(rng);
  for (float& v : m.opacity_logits) v = 6.f * u(rng);
  for (float& v : m.sh_dc) v = 2.f * u(rng);
  for (float& v : m.quats) v = u(rng);
  for (float& v : m.sh_rest) v = 3.9f * u(rng);
  return m;
}

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

// Bounds: a chunk's range over 2^bits - 1 steps, half a step of error
// (positions and log-scales 11-10-11 bits, colours 8 bits in RGB, i.e. /C0
// in SH DC), alpha half of 1/255, rotations as in SPZ version 3 with 10
// bits (stored components (sqrt 2 / 1023) / 2, the derived one 3 times
// that), SH 1/32 (the end buckets decode to -+4).
TEST(CompressedPlyIo, RoundTripWithinEachChunksSteps) {
  const GaussianModel in = RandomModel(1000, 3, 21);  // 3 chunks and 232
  std::vector<uint32_t> order;
  const GaussianModel out = Decode(EncodeCompressedPly(in, &order));
  ASSERT_EQ(out.size(), in.size());
  ASSERT_EQ(out.sh_degree, 3);
  std::vector<uint32_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i);
  const int bits[3] = {11, 10, 11};
  double worst_ratio = 0;  // largest error / bound over positions
  for (size_t begin = 0; begin < in.size(); begin += 256) {
    const size_t end = std::min(in.size(), begin + 256);
    double lo[9], hi[9];
    std::fill(lo, lo + 9, 1e30);
    std::fill(hi, hi + 9, -1e30);
    auto value = [&](const GaussianModel& m, size_t i, int k) -> double {
      if (k < 3) return m.means[3 * i + k];
      if (k < 6) return m.log_scales[3 * i + k - 3];
      return m.sh_dc[3 * i + k - 6];
    };
    for (size_t j = begin; j < end; ++j) {
      for (int k = 0; k < 9; ++k) {
        lo[k] = std::min(lo[k], value(in, order[j], k));
        hi[k] = std::max(hi[k], value(in, order[j], k));
      }
    }
    for (size_t j = begin; j < end; ++j) {
      const size_t i = order[j];
      for (int k = 0; k < 9; ++k) {
        const double steps = k < 6 ? (1 << bits[k % 3]) - 1 : 255;
        const double bound = (hi[k] - lo[k]) / steps / 2 + 1e-5;
        const double error = std::abs(value(in, i, k) - value(out, j, k));
        EXPECT_LE(error, bound) << "Gaussian " << i << " value " << k;
        if (k < 3) worst_ratio = std::max(worst_ratio, error / bound);
      }
      EXPECT_LE(std::abs(Sigmoid(in.opacity_logits[i]) -
                         Sigmoid(out.opacity_logits[j])),
                0.5 / 255 + 1e-6);
      const float* a = &in.quats[4 * i];
      const float* b = &out.quats[4 * j];
      const double na =
          std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3]);
      const double dot =
          (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]) / na;
      for (int k = 0; k < 4; ++k) {
        EXPECT_LE(std::abs(a[k] / na - (dot < 0 ? -1 : 1) * b[k]), 2.2e-3);
      }
      for (int k = 0; k < in.sh_rest_stride(); ++k) {
        EXPECT_LE(std::abs(in.sh_rest[i * 45 + k] - out.sh_rest[j * 45 + k]),
                  1 / 32.0 + 1e-6);
      }
    }
  }
  EXPECT_GT(worst_ratio, 0.5);  // the bound is not loose
}

TEST(CompressedPlyIo, MortonOrderKeepsChunksCompact) {
  // Two clusters 0.4 units wide at opposite corners of the scene,
  // interleaved in the input: each chunk must come from one cluster, so
  // its range is the cluster's and the error a step of 0.4, not of 200.
  GaussianModel in = RandomModel(512, 0, 5);
  for (size_t i = 0; i < in.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      in.means[3 * i + k] =
          (i % 2 ? 100.f : -100.f) + 0.01f * in.means[3 * i + k];
    }
  }
  std::vector<uint32_t> order;
  const GaussianModel out = Decode(EncodeCompressedPly(in, &order));
  for (size_t j = 0; j < 512; ++j) {
    EXPECT_EQ(order[j] % 2, order[j < 256 ? 0 : 256] % 2) << j;
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE(std::abs(out.means[3 * j + k] - in.means[3 * order[j] + k]),
                0.4 / 1023 / 2 + 1e-4);
    }
  }
}

// splat-transform's code: 10 bits per axis over the bounding box,
// interleaved with z highest and x lowest, so the corners of a cube come in
// the order 4z + 2y + x.
TEST(CompressedPlyIo, MortonOrderInterleavesZYX) {
  const float corners[8][3] = {{1, 1, 1}, {0, 0, 0}, {1, 0, 1}, {0, 1, 0},
                               {1, 1, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 1}};
  GaussianModel model = RandomModel(8, 0, 2);
  for (int i = 0; i < 8; ++i) {
    for (int k = 0; k < 3; ++k) model.means[3 * i + k] = corners[i][k];
  }
  EXPECT_EQ(MortonOrder(model),
            (std::vector<uint32_t>{1, 6, 3, 4, 5, 2, 7, 0}));
}

TEST(CompressedPlyIo, RefusesTruncatedPaddedAndMalformedFiles) {
  const std::string good = EncodeCompressedPly(RandomModel(300, 1, 8));
  EXPECT_EQ(Decode(good).size(), 300u);
  EXPECT_NE(Refusal(good.substr(0, good.size() - 10)).find("truncated"),
            std::string::npos);
  EXPECT_NE(Refusal(good.substr(0, 200)).find("end_header"), std::string::npos);
  EXPECT_NE(Refusal(good + "xyz").find("3 bytes after the data"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "element chunk 2", "element chunk 3"))
                .find("3 chunks for 300 vertices"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "element sh 300", "element sh 299"))
                .find("299 rows for 300 vertices"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "property uint packed_color",
                            "property float packed_color"))
                .find("must be uint"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "property uint packed_color",
                            "property uint packed_colour"))
                .find("unexpected property packed_colour"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "property float max_b\n", ""))
                .find("lacks property max_b"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "binary_little_endian", "ascii"))
                .find("binary_little_endian"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "property uchar f_rest_8\n", ""))
                .find("8 properties"),
            std::string::npos);
  EXPECT_NE(Refusal(Replace(good, "element vertex", "element vertices"))
                .find("in that order"),
            std::string::npos);
  std::string nan = good;
  const size_t data = nan.find("end_header\n") + 11;
  const float value = std::nanf("");
  std::memcpy(&nan[data + 4], &value, 4);
  EXPECT_NE(Refusal(nan).find("chunk 0 has a NaN/Inf min_y"),
            std::string::npos);
  EXPECT_NE(Refusal("ply\nformat binary_little_endian 1.0\nelement chunk "
                    "99999999999\nend_header\n")
                .find("needs elements chunk and vertex"),
            std::string::npos);
}

TEST(CompressedPlyIo, DetectsTheSchemaByItsChunkElement) {
  const std::string compressed = EncodeCompressedPly(RandomModel(3, 0, 1));
  EXPECT_TRUE(IsCompressedPlyHeader(
      reinterpret_cast<const uint8_t*>(compressed.data()), compressed.size()));
  const std::string plain =
      "ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
      "property float x\nend_header\n";
  EXPECT_FALSE(IsCompressedPlyHeader(
      reinterpret_cast<const uint8_t*>(plain.data()), plain.size()));
}

}  // namespace
}  // namespace watergs
