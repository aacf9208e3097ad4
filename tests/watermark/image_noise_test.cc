// 2D noise layers: each Backward is the exact adjoint of its (linear in the
// watermarked image) Forward, checked with the dot-product test in double;
// JPEG is straight-through; the layers do what their names say.
#include "watermark/image_noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

Tensor RandomTensor(int n, int h, int w, std::mt19937* rng) {
  Tensor t(n, 3, h, w);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  for (float& v : t.data) v = dist(*rng);
  return t;
}

double Dot(const Tensor& a, const Tensor& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += double(a.data[i]) * b.data[i];
  return s;
}

// <N(x) - N(0), y> == <x, N^T y> for the noise realisation drawn with `seed`
// (N is affine in x: the cover enters as a constant).
void ExpectAdjoint(NoiseKind kind) {
  std::mt19937 rng(1);
  const Tensor x = RandomTensor(2, 13, 17, &rng);
  const Tensor cover = RandomTensor(2, 13, 17, &rng);
  Tensor zero = x, out, out0;
  zero.Fill(0.f);
  ImageNoise noise;
  std::mt19937 draw(42);
  noise.Forward(kind, zero, cover, &out0, &draw);
  draw.seed(42);
  noise.Forward(kind, x, cover, &out, &draw);
  ASSERT_TRUE(out.SameShape(out0));
  Tensor y = out;
  for (float& v : y.data) v = std::uniform_real_distribution<float>(-1, 1)(rng);
  Tensor x_adjoint;
  noise.Backward(y, &x_adjoint);
  ASSERT_TRUE(x_adjoint.SameShape(x));
  const double lhs = Dot(out, y) - Dot(out0, y);
  EXPECT_NEAR(lhs, Dot(x, x_adjoint), 1e-4 * (1 + std::abs(lhs)))
      << NoiseName(kind);
}

TEST(ImageNoiseTest, BackwardIsTheAdjointOfForward) {
  for (NoiseKind kind :
       {NoiseKind::kIdentity, NoiseKind::kCrop, NoiseKind::kDropout,
        NoiseKind::kResize, NoiseKind::kBlur})
    ExpectAdjoint(kind);
}

TEST(ImageNoiseTest, LayersChangeTheImageAsNamed) {
  std::mt19937 rng(2);
  const Tensor wm = RandomTensor(1, 40, 50, &rng);
  Tensor cover = wm;
  for (float& v : cover.data) v = -v;
  ImageNoise noise;
  Tensor out;
  noise.Forward(NoiseKind::kCrop, wm, cover, &out, &rng);
  EXPECT_EQ(out.h, 28);  // 0.7 of each side
  EXPECT_EQ(out.w, 35);
  noise.Forward(NoiseKind::kResize, wm, cover, &out, &rng);
  EXPECT_LE(out.h, 40);
  EXPECT_GE(out.h, 20);
  noise.Forward(NoiseKind::kDropout, wm, cover, &out, &rng);
  size_t from_cover = 0;
  for (size_t i = 0; i < out.PlaneSize(); ++i)
    from_cover += out.data[i] == cover.data[i] && out.data[i] != wm.data[i];
  EXPECT_NEAR(double(from_cover) / out.PlaneSize(), 0.3, 0.06);
  // Blur keeps a constant image and lowers the variance of noise.
  noise.Forward(NoiseKind::kBlur, wm, cover, &out, &rng);
  double before = 0, after = 0;
  for (size_t i = 0; i < wm.size(); ++i) {
    before += wm.data[i] * wm.data[i];
    after += out.data[i] * out.data[i];
  }
  EXPECT_LT(after, 0.3 * before);
  Tensor flat = wm;
  flat.Fill(0.25f);
  noise.Forward(NoiseKind::kBlur, flat, cover, &out, &rng);
  for (float v : out.data) ASSERT_NEAR(v, 0.25f, 1e-5);
}

TEST(ImageNoiseTest, JpegIsLossyAndStraightThrough) {
  std::mt19937 rng(3);
  Tensor smooth(1, 3, 32, 32);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x)
        smooth.Plane(0, c)[y * 32 + x] =
            std::sin(0.2f * x + c) * 0.5f + 0.1f * y / 32;
  ImageNoise noise;
  Tensor out, grad;
  noise.Forward(NoiseKind::kJpeg, smooth, smooth, &out, &rng);
  double mse = 0;
  bool changed = false;
  for (size_t i = 0; i < out.size(); ++i) {
    mse += (out.data[i] - smooth.data[i]) * (out.data[i] - smooth.data[i]) / 4;
    changed |= std::abs(out.data[i] - smooth.data[i]) > 1.f / 255;
  }
  EXPECT_TRUE(changed);
  EXPECT_GT(-10 * std::log10(mse / out.size()), 28.0);  // close, in [0,1] units
  Tensor dy = RandomTensor(1, 32, 32, &rng);
  noise.Backward(dy, &grad);
  EXPECT_EQ(grad.data, dy.data);
}

TEST(ImageNoiseTest, ParsesNoiseLists) {
  EXPECT_EQ(ParseNoiseList("identity,jpeg").size(), 2u);
  EXPECT_EQ(ParseNoiseList("blur")[0], NoiseKind::kBlur);
  EXPECT_THROW(ParseNoiseList("identity,sharpen"), Error);
  EXPECT_THROW(ParseNoiseList(""), Error);
}

}  // namespace
}  // namespace watergs
