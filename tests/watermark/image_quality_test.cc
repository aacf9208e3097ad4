// Tests of MS-SSIM: the number of scales for each image size, the value for
// identical images, the closed form for constant images (only the luminance
// term of the coarsest scale differs from 1), symmetry and ordering by noise.
#include "watermark/image_quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

ImageRGB Constant(int w, int h, float value) {
  ImageRGB image(w, h);
  for (float& v : image.data) v = value;
  return image;
}

ImageRGB Noisy(const ImageRGB& image, float sigma, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, sigma);
  ImageRGB out = image;
  for (float& v : out.data) v = std::clamp(v + noise(rng), 0.f, 1.f);
  return out;
}

TEST(MsSsim, ScalesFollowTheImageSize) {
  EXPECT_EQ(MsSsimScales(176, 176), 5);
  EXPECT_EQ(MsSsimScales(480, 360), 5);
  EXPECT_EQ(MsSsimScales(175, 400), 4);  // 175 >> 4 = 10 < 11
  EXPECT_EQ(MsSsimScales(48, 36), 2);    // 36, 18, then 9
  EXPECT_EQ(MsSsimScales(11, 11), 1);
  EXPECT_EQ(MsSsimScales(10, 100), 0);
  EXPECT_TRUE(
      std::isnan(MsSsim(Constant(8, 8, 0.5f), Constant(8, 8, 0.5f)).value));
}

TEST(MsSsim, ConstantImagesGiveTheLuminanceTermToItsWeight) {
  // Zero variance everywhere: every cs term is C2 / C2 = 1, and the coarsest
  // scale's luminance term is (2ab + C1) / (a^2 + b^2 + C1). Five scales use
  // the published weights unnormalised (they sum to 1.0001).
  const double a = double(0.3f), b = double(0.55f), c1 = 1e-4;
  const double luminance = (2 * a * b + c1) / (a * a + b * b + c1);
  const MsSsimResult five =
      MsSsim(Constant(176, 180, 0.3f), Constant(176, 180, 0.55f));
  EXPECT_EQ(five.scales, 5);
  EXPECT_NEAR(five.value, std::pow(luminance, 0.1333), 1e-6);
  // Two scales: weights 0.0448 and 0.2856 renormalised.
  const MsSsimResult two =
      MsSsim(Constant(48, 36, 0.3f), Constant(48, 36, 0.55f));
  EXPECT_EQ(two.scales, 2);
  EXPECT_NEAR(two.value, std::pow(luminance, 0.2856 / (0.0448 + 0.2856)), 1e-6);
}

TEST(MsSsim, IsOneForIdenticalImagesSymmetricAndFallsWithNoise) {
  const ImageRGB image = Noisy(Constant(192, 180, 0.5f), 0.2f, 1);
  EXPECT_NEAR(MsSsim(image, image).value, 1.0, 1e-12);
  const ImageRGB light = Noisy(image, 0.02f, 2);
  const ImageRGB heavy = Noisy(image, 0.1f, 3);
  EXPECT_NEAR(MsSsim(image, light).value, MsSsim(light, image).value, 1e-12);
  EXPECT_LT(MsSsim(image, light).value, 1.0);
  EXPECT_LT(MsSsim(image, heavy).value, MsSsim(image, light).value);
  EXPECT_THROW(MsSsim(image, Constant(10, 10, 0.f)), Error);
}

}  // namespace
}  // namespace watergs
