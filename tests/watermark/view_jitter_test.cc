// The decoder jitter of embedding (watermark/view_jitter.h): the resampling
// and its adjoint, which carries the message gradient back to the render.
#include "watermark/view_jitter.h"

#include <gtest/gtest.h>

#include <random>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

ImageRGB RandomImage(int w, int h, std::mt19937_64* rng) {
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  ImageRGB image(w, h);
  for (float& v : image.data) v = unit(*rng);
  return image;
}

double Dot(const ImageRGB& a, const ImageRGB& b) {
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i)
    sum += double(a.data[i]) * b.data[i];
  return sum;
}

TEST(ViewJitter, NoShiftNoZoomIsTheIdentity) {
  std::mt19937_64 rng(1);
  const ImageRGB image = RandomImage(37, 23, &rng);
  JitterSample sample;
  sample.width = 37;
  sample.height = 23;
  ImageRGB out;
  JitterForward(image, sample, &out);
  EXPECT_EQ(out.data, image.data);
}

TEST(ViewJitter, WholePixelShiftMovesTheImage) {
  std::mt19937_64 rng(2);
  const ImageRGB image = RandomImage(20, 10, &rng);
  JitterSample sample;
  sample.dx = 2;
  sample.dy = 1;
  sample.width = 20;
  sample.height = 10;
  ImageRGB out;
  JitterForward(image, sample, &out);
  for (int y = 0; y + 1 < 10; ++y)
    for (int x = 0; x + 2 < 20; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_FLOAT_EQ(out.At(x, y)[c], image.At(x + 2, y + 1)[c]);
}

// <J x, g> = <x, J^T g> for random draws: the adjoint is the transpose of
// the (linear) resampling, edges and zoom included.
TEST(ViewJitter, AdjointIsTheTransposeOfTheResampling) {
  std::mt19937_64 rng(3);
  DecoderJitterOptions options;
  options.max_shift = 3;
  options.min_scale = 0.5;
  options.max_scale = 1.5;
  for (int trial = 0; trial < 20; ++trial) {
    const ImageRGB x = RandomImage(31, 17, &rng);
    const JitterSample sample = SampleJitter(options, 31, 17, &rng);
    ImageRGB jx;
    JitterForward(x, sample, &jx);
    ASSERT_EQ(jx.width, sample.width);
    const ImageRGB g = RandomImage(sample.width, sample.height, &rng);
    ImageRGB jtg(31, 17);
    JitterAdjoint(g, sample, &jtg);
    const double lhs = Dot(jx, g), rhs = Dot(x, jtg);
    EXPECT_NEAR(lhs, rhs, 1e-4 * std::abs(lhs)) << "trial " << trial;
  }
}

TEST(ViewJitter, SamplesStayInTheirRanges) {
  std::mt19937_64 rng(4);
  DecoderJitterOptions options;
  options.max_shift = 2;
  options.min_scale = 0.5;
  options.max_scale = 1;
  for (int k = 0; k < 200; ++k) {
    const JitterSample s = SampleJitter(options, 240, 180, &rng);
    EXPECT_GE(s.scale, 0.5 - 1e-12);
    EXPECT_LE(s.scale, 1 + 1e-12);
    EXPECT_LE(std::abs(s.dx), 2);
    EXPECT_LE(std::abs(s.dy), 2);
    EXPECT_GE(s.width, 120);
    EXPECT_LE(s.width, 240);
  }
}

TEST(ViewJitter, RefusesRangesItCannotSample) {
  DecoderJitterOptions bad;
  bad.min_scale = 0.25;
  EXPECT_THROW(CheckDecoderJitter(bad), Error);
  bad = DecoderJitterOptions();
  bad.max_shift = -1;
  EXPECT_THROW(CheckDecoderJitter(bad), Error);
  bad = DecoderJitterOptions();
  bad.min_scale = 1.2;
  bad.max_scale = 1.1;
  EXPECT_THROW(CheckDecoderJitter(bad), Error);
  EXPECT_NO_THROW(CheckDecoderJitter(DecoderJitterOptions()));
}

}  // namespace
}  // namespace watergs
