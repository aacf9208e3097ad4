// The default decoder shipped in watermark/models/decoder_48.bin (a
// random-feature decoder made by `watergs make_decoder`,
// docs/decoder_design.md): it is small, reads 48 bits, is steerable on held-out
// photos (tests/data/photos) at a small pixel change, finds no message in
// unmarked crops of them, and a corrupted or truncated copy is refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "gaussian/error.h"
#include "gaussian/file_util.h"
#include "tests/common/corrupt_copies.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

const std::string kModel =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";
const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";

TEST(DefaultDecoderTest, IsASmallFortyEightBitFeatureDecoder) {
  EXPECT_LE(std::filesystem::file_size(kModel), 5u << 20);
  const NetworkFile file = ReadNetworkFile(kModel);
  EXPECT_EQ(file.kind, kFeatureDecoderKind);
  std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(kModel, Device::kCpu, 48);
  EXPECT_EQ(decoder->NumBits(), 48);
}

// Every bit of a random message set on 128 px held-out crops by pixel-space
// Adam, above 25 dB; no unmarked crop passes the verdict for that message.
TEST(DefaultDecoderTest, SteerableAndBalancedOnHeldOutPhotos) {
  std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(kModel, Device::kCpu, 48);
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  const std::vector<ImageRGB> crops = SamplePhotoCrops(photos, 128, 400, 17);
  std::mt19937 rng(29);
  Bits target(48);
  for (auto& b : target) b = rng() & 1;
  for (int i = 0; i < 3; ++i) {
    const SteerResult r =
        SteerPixels(*decoder, crops[i * 50], target, 400, 0.002, 0.5);
    EXPECT_EQ(r.bit_errors, 0) << i;
    EXPECT_GT(r.psnr, 25.0) << i;
  }
  const DecoderBalance balance = MeasureBalance(*decoder, crops, target);
  EXPECT_EQ(balance.false_positives, 0);
  EXPECT_GT(balance.ones_fraction, 0.4);
  EXPECT_LT(balance.ones_fraction, 0.6);
  // (Bit correlations are not asserted here: 400 crops of 8 photos measure
  // mostly which photo a crop came from; docs/decoder_design.md gives the
  // corpus figure over 1,000 crops of 16 held-out photos.)
}

TEST(DefaultDecoderTest, RefusesCorruptedAndTruncatedCopies) {
  testing::ExpectCorruptCopiesRefused(kModel, [](const std::string& copy) {
    LoadBitDecoder(copy, Device::kCpu);
  });
}

}  // namespace
}  // namespace watergs
