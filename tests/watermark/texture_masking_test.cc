// TextureMaskingWeights: flat images weigh 1 everywhere, textured regions
// weigh less than flat ones, the mean is 1, and the local deviation is the
// brute-force one.
#include "watermark/texture_masking.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <random>

namespace watergs {
namespace {

ImageRGB Image(int w, int h) {
  ImageRGB image;
  image.width = w;
  image.height = h;
  image.data.assign(size_t(w) * h * 3, 0.5f);
  return image;
}

TEST(TextureMasking, FlatIsOneTextureWeighsLessMeanIsOne) {
  const ImageRGB flat = Image(40, 30);
  for (float w : TextureMaskingWeights(flat, 0.05)) EXPECT_NEAR(w, 1.f, 1e-5);

  // Left half noise, right half flat.
  ImageRGB half = Image(40, 30);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 20; ++x) {
      const float v = u(rng);
      for (int c = 0; c < 3; ++c) half.data[(size_t(y) * 40 + x) * 3 + c] = v;
    }
  }
  const std::vector<float> w = TextureMaskingWeights(half, 0.05);
  EXPECT_NEAR(std::accumulate(w.begin(), w.end(), 0.0) / w.size(), 1.0, 1e-4);
  // Noise of deviation ~0.29: 1 / (1 + 0.29 / 0.05) ~ 0.15 of the flat weight.
  const float textured = w[15 * 40 + 5], plain = w[15 * 40 + 35];
  EXPECT_LT(textured, 0.25f * plain);
  // The brute-force deviation over the 7x7 window at an interior pixel.
  double sum = 0, sum_sq = 0;
  for (int dy = -3; dy <= 3; ++dy) {
    for (int dx = -3; dx <= 3; ++dx) {
      const float* p = &half.data[(size_t(15 + dy) * 40 + 5 + dx) * 3];
      const double luma = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
      sum += luma;
      sum_sq += luma * luma;
    }
  }
  const double sigma = std::sqrt(sum_sq / 49 - (sum / 49) * (sum / 49));
  EXPECT_NEAR(textured / plain, 1 / (1 + sigma / 0.05), 1e-3);
}

}  // namespace
}  // namespace watergs
