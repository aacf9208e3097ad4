// Tests of the attacks on rendered images: JPEG quantises to 8 bits and loses
// more at lower quality, resize has the requested size and INTER_AREA's block
// means, crop keeps the centred window, and bad specs are refused.
#include "watermark/image_attacks.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Smooth colour waves, values in [0.1, 0.9] (low frequencies: JPEG at high
// quality keeps them, including through its chroma subsampling).
ImageRGB TestImage(int w, int h) {
  ImageRGB image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        image.At(x, y)[c] = 0.5f + 0.3f * std::sin(0.21f * x + 0.13f * y + c) +
                            0.1f * std::cos(0.3f * y - 0.2f * x * c);
      }
    }
  }
  return image;
}

double MeanAbsError(const ImageRGB& a, const ImageRGB& b) {
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i)
    sum += std::abs(a.data[i] - b.data[i]);
  return sum / a.data.size();
}

TEST(ImageAttacks, JpegQuantisesAndLosesMoreAtLowQuality) {
  const ImageRGB image = TestImage(64, 48);
  const ImageRGB high = ApplyImageAttack(ParseImageAttack("jpeg:95"), image);
  const ImageRGB low = ApplyImageAttack(ParseImageAttack("jpeg:10"), image);
  ASSERT_EQ(high.width, 64);
  ASSERT_EQ(high.height, 48);
  for (float v : high.data) {
    EXPECT_NEAR(v * 255.f, std::round(v * 255.f), 1e-3f);  // 8-bit values
  }
  // Quality 95 stays within a few 8-bit levels on average; 10 is worse.
  EXPECT_LT(MeanAbsError(high, image), 4.0 / 255);
  EXPECT_GT(MeanAbsError(low, image), 2 * MeanAbsError(high, image));
}

TEST(ImageAttacks, ResizeHasTheSizeAndAveragesBlocksWhenHalving) {
  const ImageRGB image = TestImage(40, 30);
  const ImageRGB half = ApplyImageAttack(ParseImageAttack("resize:0.5"), image);
  ASSERT_EQ(half.width, 20);
  ASSERT_EQ(half.height, 15);
  for (int y = 0; y < 15; ++y) {
    for (int x = 0; x < 20; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float mean =
            0.25f *
            (image.At(2 * x, 2 * y)[c] + image.At(2 * x + 1, 2 * y)[c] +
             image.At(2 * x, 2 * y + 1)[c] + image.At(2 * x + 1, 2 * y + 1)[c]);
        EXPECT_NEAR(half.At(x, y)[c], mean, 1e-5f);
      }
    }
  }
  const ImageRGB twice = ApplyImageAttack(ParseImageAttack("resize:2"), image);
  EXPECT_EQ(twice.width, 80);
  EXPECT_EQ(twice.height, 60);
  const ImageRGB tiny =
      ApplyImageAttack(ParseImageAttack("resize:0.01"), image);
  EXPECT_EQ(tiny.width, 1);
  EXPECT_EQ(tiny.height, 1);
}

TEST(ImageAttacks, CropKeepsTheCentredWindow) {
  const ImageRGB image = TestImage(40, 30);
  const ImageRGB crop = ApplyImageAttack(ParseImageAttack("crop:0.5"), image);
  ASSERT_EQ(crop.width, 20);
  ASSERT_EQ(crop.height, 15);
  for (int y = 0; y < 15; ++y) {
    for (int x = 0; x < 20; ++x) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(crop.At(x, y)[c], image.At(10 + x, 7 + y)[c]);
      }
    }
  }
  EXPECT_EQ(ApplyImageAttack(ParseImageAttack("crop:1"), image).data,
            image.data);
}

TEST(ImageAttacks, TheOwnerDecodesAResizedCopyAtTheRenderSize) {
  const ImageRGB image = TestImage(40, 30);
  // Halved then brought back: the render's size, close to it (smooth image),
  // and exactly the bilinear enlargement of the halved copy.
  const ImageRGB back = AttackAsDecoded(ParseImageAttack("resize:0.5"), image);
  ASSERT_EQ(back.width, 40);
  ASSERT_EQ(back.height, 30);
  EXPECT_LT(MeanAbsError(back, image), 0.03);
  const ImageRGB half = ApplyImageAttack(ParseImageAttack("resize:0.5"), image);
  EXPECT_EQ(back.data, ResizeTo(half, 40, 30).data);
  EXPECT_GT(MeanAbsError(back, image), 0);  // not the render itself
  // A crop keeps its pixels (the scale is unchanged); JPEG keeps the size.
  EXPECT_EQ(AttackAsDecoded(ParseImageAttack("crop:0.5"), image).width, 20);
  EXPECT_EQ(AttackAsDecoded(ParseImageAttack("jpeg:50"), image).width, 40);
  EXPECT_EQ(ResizeTo(image, 40, 30).data, image.data);
  EXPECT_THROW(ResizeTo(image, 0, 30), Error);
}

TEST(ImageAttacks, ParsesAndRefusesBadSpecs) {
  const auto list = ParseImageAttackList("jpeg:50,resize:0.75,crop:0.6");
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[1].kind, ImageAttackKind::kResize);
  EXPECT_DOUBLE_EQ(list[2].value, 0.6);
  for (const auto& spec : list) {
    EXPECT_EQ(ToString(ParseImageAttack(ToString(spec))), ToString(spec));
  }
  for (const char* bad :
       {"jpeg:0", "jpeg:101", "jpeg:50.5", "jpeg", "resize:0", "resize:5",
        "crop:1.5", "crop:0", "blur:3", "crop:x"}) {
    EXPECT_THROW(ParseImageAttack(bad), Error) << bad;
  }
}

}  // namespace
}  // namespace watergs
