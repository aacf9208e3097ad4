// Tests of the antimatter15 .splat reader and writer: values of a hand-built
// record, round-trip error bounds from the 8-bit steps (the writer truncates
// as splat-transform does), scale 0 read as the log-scale floor, and
// one-line refusals of sizes and values no .splat file holds.
#include "gaussian/formats/splat_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

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

std::string Record(const float pos[3], const float scale[3],
                   const uint8_t rgba[4], const uint8_t rot[4]) {
  std::string r;
  for (int k = 0; k < 3; ++k) PutF32(pos[k], &r);
  for (int k = 0; k < 3; ++k) PutF32(scale[k], &r);
  r.append(reinterpret_cast<const char*>(rgba), 4);
  r.append(reinterpret_cast<const char*>(rot), 4);
  return r;
}

GaussianModel Decode(const std::string& bytes, size_t* replaced = nullptr) {
  return DecodeSplat("test.splat",
                     reinterpret_cast<const uint8_t*>(bytes.data()),
                     bytes.size(), replaced);
}

// The one-line error for `bytes` (tests/common/refusal.h).
std::string Refusal(const std::string& bytes) {
  return testing::Refusal("test.splat", [&] { Decode(bytes); });
}

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

TEST(SplatIo, DecodesAHandBuiltRecord) {
  const float pos[] = {1.5f, -2.f, 1e-3f}, scale[] = {0.5f, 2.f, 0.f};
  const uint8_t rgba[] = {255, 0, 128, 191}, rot[] = {192, 128, 64, 128};
  const std::string bytes =
      Record(pos, scale, rgba, rot) + Record(pos, scale, rgba, rot);
  size_t replaced = 0;
  const GaussianModel m = Decode(bytes, &replaced);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m.sh_degree, 0);
  EXPECT_EQ(replaced, 2u);  // one zero scale per record
  for (int k = 0; k < 3; ++k) EXPECT_EQ(m.means[k], pos[k]);
  EXPECT_NEAR(m.log_scales[0], std::log(0.5), 1e-6);
  EXPECT_NEAR(m.log_scales[1], std::log(2.0), 1e-6);
  EXPECT_EQ(m.log_scales[2], kLogScaleFloor);  // scale 0: not -Inf
  EXPECT_NEAR(m.sh_dc[0], 0.5 / kShC0, 1e-5);
  EXPECT_NEAR(m.sh_dc[1], -0.5 / kShC0, 1e-5);
  EXPECT_NEAR(m.sh_dc[2], (128 / 255.0 - 0.5) / kShC0, 1e-5);
  EXPECT_NEAR(m.opacity_logits[0], std::log(191.0 / 64.0), 1e-5);
  // Rotation bytes (b - 128) / 128 in w x y z order, normalised: (0.5, 0,
  // -0.5, 0) / |.|.
  const double s = std::sqrt(0.5);
  const double q[] = {s, 0, -s, 0};
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(m.quats[k], q[k], 1e-6);
}

TEST(SplatIo, AlphaBytesOfZeroAndFullAreFinite) {
  const float pos[] = {0, 0, 0}, scale[] = {1, 1, 1};
  const uint8_t none[] = {0, 0, 0, 0}, full[] = {0, 0, 0, 255},
                rot[] = {255, 128, 128, 128};
  const GaussianModel m =
      Decode(Record(pos, scale, none, rot) + Record(pos, scale, full, rot));
  EXPECT_EQ(m.opacity_logits[0], -kOpacityLogitLimit);
  EXPECT_EQ(m.opacity_logits[1], kOpacityLogitLimit);
}

// Steps: positions and scales are float32 (exact and exp/log rounding);
// colour 1/255 in RGB, i.e. 1/(255 C0) in SH DC, alpha 1/255, rotation
// bytes 1/128 per component before normalising, all truncated (error below
// one step, not half). SH above degree 0 is not stored.
TEST(SplatIo, RoundTripWithinTruncationSteps) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel in;
  in.sh_degree = 2;
  in.Resize(400);
  for (float& v : in.means) v = 50.f * u(rng);
  for (float& v : in.log_scales) v = -6.f + 4.f * u(rng);
  for (float& v : in.opacity_logits) v = 5.f * u(rng);
  for (float& v : in.sh_dc) v = 1.7f * u(rng);  // RGB in (0.02, 0.98)
  for (float& v : in.quats) v = u(rng);
  for (float& v : in.sh_rest) v = u(rng);
  const std::string bytes = EncodeSplat(in);
  ASSERT_EQ(bytes.size(), 32 * in.size());
  const GaussianModel out = Decode(bytes);
  ASSERT_EQ(out.size(), in.size());
  EXPECT_EQ(out.sh_degree, 0);
  double worst_dc = 0, worst_alpha = 0, worst_rot = 0, worst_scale = 0;
  for (size_t i = 0; i < in.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(in.means[3 * i + k], out.means[3 * i + k]);
      worst_scale =
          std::max(worst_scale, double(std::abs(in.log_scales[3 * i + k] -
                                                out.log_scales[3 * i + k])));
      worst_dc = std::max(worst_dc, double(std::abs(in.sh_dc[3 * i + k] -
                                                    out.sh_dc[3 * i + k])));
    }
    worst_alpha =
        std::max(worst_alpha, std::abs(Sigmoid(in.opacity_logits[i]) -
                                       Sigmoid(out.opacity_logits[i])));
    const float* a = &in.quats[4 * i];
    const double n =
        std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3]);
    for (int k = 0; k < 4; ++k) {
      worst_rot =
          std::max(worst_rot, std::abs(a[k] / n - out.quats[4 * i + k]));
    }
  }
  EXPECT_LE(worst_scale, 1e-6);
  EXPECT_LE(worst_dc, 1 / (255 * kShC0) + 1e-6);
  EXPECT_LE(worst_alpha, 1 / 255.0 + 1e-6);
  // Under 1/128 per component, plus |q_k| times the renormalisation of the
  // truncated vector (its norm within 2/128 of 1): under 3/128.
  EXPECT_LE(worst_rot, 3.1 / 128);
  EXPECT_GT(worst_dc, 0.5 / (255 * kShC0));  // truncation, not rounding
}

TEST(SplatIo, RefusesWhatNoSplatFileHolds) {
  const float pos[] = {0, 0, 0}, scale[] = {1, 1, 1};
  const uint8_t rgba[] = {1, 2, 3, 4}, rot[] = {255, 128, 128, 128};
  const std::string good = Record(pos, scale, rgba, rot);
  EXPECT_NE(Refusal("").find("empty"), std::string::npos);
  EXPECT_NE(Refusal(good + good.substr(0, 31)).find("not a multiple of"),
            std::string::npos);
  const float nan_pos[] = {0, std::nanf(""), 0};
  EXPECT_NE(Refusal(good + Record(nan_pos, scale, rgba, rot))
                .find("Gaussian 1 has a NaN/Inf position"),
            std::string::npos);
  const float negative[] = {1, -0.5f, 1};
  EXPECT_NE(Refusal(Record(pos, negative, rgba, rot)).find("scale"),
            std::string::npos);
  const float inf[] = {1, std::numeric_limits<float>::infinity(), 1};
  EXPECT_NE(Refusal(Record(pos, inf, rgba, rot)).find("scale"),
            std::string::npos);
}

TEST(SplatIo, WriterRefusesNonFiniteModels) {
  GaussianModel in;
  in.sh_degree = 0;
  in.Resize(2);
  in.quats[0] = 1;
  in.sh_dc[4] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(EncodeSplat(in), Error);
}

}  // namespace
}  // namespace watergs
