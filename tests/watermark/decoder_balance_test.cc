// MeasureBalance (feature_decoder_calibration.h), the figures behind
// `decoder_stats` and the README's false-positive claims, on a stub decoder
// whose logits are set by hand: exact fractions of 1-bits, per-bit balance,
// mean |correlation|, bit errors, and a false-positive counter that counts
// exactly the images within the verdict's error budget (a counter that never
// increments must fail here).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "watermark/bit_decoder.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

// Reads image k (a 1x1 image whose first value is k) as logits[k].
class StubDecoder : public BitDecoder {
 public:
  explicit StubDecoder(std::vector<std::vector<float>> logits)
      : logits_(std::move(logits)) {}
  int NumBits() const override { return int(logits_.at(0).size()); }
  std::vector<float> Logits(const ImageRGB& image) override {
    return logits_.at(size_t(image.data.at(0)));
  }
  void InputGradient(const ImageRGB&, const std::vector<float>&,
                     ImageRGB*) override {
    Fail("StubDecoder: no gradient");
  }

 private:
  std::vector<std::vector<float>> logits_;
};

// Images 0..count-1 for the stub.
std::vector<ImageRGB> StubImages(int count) {
  std::vector<ImageRGB> images;
  for (int k = 0; k < count; ++k) {
    ImageRGB image(1, 1);
    image.data = {float(k), 0.f, 0.f};
    images.push_back(image);
  }
  return images;
}

// Four images, four bits (one row per image):
//   bit 0: +1 -1 +1 -1   half ones
//   bit 1: +2 -2 +2 -2   bit 0 scaled: |correlation| 1 with it
//   bit 2: +1 +1 +1 -3   3 of 4 ones; |correlation| 1/sqrt(3) with bits 0, 1
//   bit 3: -1 -1 -1 -1   never a one; constant, so correlation 0 with all
// Ones: 2 + 2 + 3 + 0 = 7 of 16. Ordered pairs a != b: 12, of |correlation|
// sum 2 (1 + 2/sqrt(3)).
TEST(MeasureBalanceTest, ExactFiguresOfKnownLogits) {
  StubDecoder decoder(
      {{1, 2, 1, -1}, {-1, -2, 1, -1}, {1, 2, 1, -1}, {-1, -2, -3, -1}});
  const std::vector<ImageRGB> images = StubImages(4);
  const Bits claimed = {1, 1, 1, 0};
  const DecoderBalance b = MeasureBalance(decoder, images, claimed);
  EXPECT_EQ(b.images, 4);
  EXPECT_DOUBLE_EQ(b.ones_fraction, 7.0 / 16.0);
  EXPECT_DOUBLE_EQ(b.min_bit_ones, 0.0);
  EXPECT_DOUBLE_EQ(b.max_bit_ones, 0.75);
  EXPECT_NEAR(b.mean_abs_correlation, 2 * (1 + 2 / std::sqrt(3.0)) / 12, 1e-12);
  ASSERT_EQ(b.image_bits.size(), 4u);
  EXPECT_EQ(b.image_bits[0], (Bits{1, 1, 1, 0}));
  EXPECT_EQ(b.image_bits[1], (Bits{0, 0, 1, 0}));
  EXPECT_EQ(b.image_bits[3], (Bits{0, 0, 0, 0}));
  // Errors against the claim: 0, 2, 0, 3.
  EXPECT_EQ(b.min_bit_errors, 0);
  // 4 of 4 bits right has p = 1/16, 2 of 4 11/16, 1 of 4 15/16: at p <= 0.1
  // images 0 and 2 pass, at p <= 0.7 image 1 too; at the default 1e-6 none
  // can.
  EXPECT_EQ(b.false_positives, 0);
  EXPECT_EQ(MeasureBalance(decoder, images, claimed, 0.1).false_positives, 2);
  EXPECT_EQ(MeasureBalance(decoder, images, claimed, 0.7).false_positives, 3);
  // Against 0001: 4, 2, 4 and 1 errors.
  EXPECT_EQ(MeasureBalance(decoder, images, {0, 0, 0, 1}).min_bit_errors, 1);
  // The lean: means 0, 0, 0, -1; population deviations 1, 2, sqrt(3), 0.
  ASSERT_EQ(b.bit_mean.size(), 4u);
  EXPECT_DOUBLE_EQ(b.bit_mean[0], 0);
  EXPECT_DOUBLE_EQ(b.bit_mean[2], 0);
  EXPECT_DOUBLE_EQ(b.bit_mean[3], -1);
  EXPECT_DOUBLE_EQ(b.bit_std[0], 1);
  EXPECT_DOUBLE_EQ(b.bit_std[1], 2);
  EXPECT_NEAR(b.bit_std[2], std::sqrt(3.0), 1e-12);
  EXPECT_DOUBLE_EQ(b.bit_std[3], 0);
}

// 48 bits at the verdict's 1e-6: an image reading the claim exactly counts
// (the positive case a steered image is), one with as many errors as the
// verdict allows counts, one more error does not, and the complement reads
// 48 errors.
TEST(MeasureBalanceTest, CountsExactlyTheImagesTheVerdictWouldCallPresent) {
  const int allowed = MaxErrorsForPresence(48, 1e-6);
  ASSERT_EQ(allowed, 7);
  Bits claimed(48);
  for (int i = 0; i < 48; ++i) claimed[i] = (i * 7 + i / 5) % 3 == 0;
  auto logits_with_errors = [&](int errors) {
    std::vector<float> z(48);
    for (int i = 0; i < 48; ++i) {
      const bool bit = bool(claimed[i]) != (i < errors);
      z[i] = bit ? 0.5f + i : -0.5f - i;
    }
    return z;
  };
  StubDecoder decoder({logits_with_errors(0), logits_with_errors(allowed),
                       logits_with_errors(allowed + 1),
                       logits_with_errors(48)});
  const std::vector<ImageRGB> images = StubImages(4);
  const DecoderBalance all = MeasureBalance(decoder, images, claimed);
  EXPECT_EQ(all.false_positives, 2);
  EXPECT_EQ(all.min_bit_errors, 0);
  EXPECT_EQ(all.image_bits[0], claimed);
  // One at a time: the steered-like image alone counts 1, the unmarked-like
  // ones 0.
  const std::vector<ImageRGB> first(images.begin(), images.begin() + 1);
  EXPECT_EQ(MeasureBalance(decoder, first, claimed).false_positives, 1);
  const std::vector<ImageRGB> rest(images.begin() + 2, images.end());
  const DecoderBalance unmarked = MeasureBalance(decoder, rest, claimed);
  EXPECT_EQ(unmarked.false_positives, 0);
  EXPECT_EQ(unmarked.min_bit_errors, allowed + 1);
}

TEST(MeasureBalanceTest, RefusesAClaimOfAnotherLength) {
  StubDecoder decoder({{1, -1}});
  EXPECT_THROW(MeasureBalance(decoder, StubImages(1), Bits{1, 0, 1}), Error);
}

}  // namespace
}  // namespace watergs
