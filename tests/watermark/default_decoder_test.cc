// The default decoder shipped in watermark/models/decoder_48.bin (a
// random-feature decoder made by `watergs make_decoder`,
// docs/decoder_design.md): it is small, reads 48 bits, is steerable on held-out
// photos (tests/data/photos) at a small pixel change, finds no message in
// unmarked crops of them, and a corrupted or truncated copy is refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
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

// The shipped file, byte for byte: the README's and docs' figures (demo
// verdicts, balance, false positives) were measured with it, so a rebuilt or
// edited decoder must change this pin together with them. Fnv1a64
// (gaussian/util/file_util.h) of all its bytes (the file's trailing checksum
// covers only the bytes before it); `sha256sum
// watermark/models/decoder_48.bin` gives
// 9cce9644c665848f29d350e9a33a42344555882f82e636fbb83fb94266aa6b51. The
// weights are those every figure was measured with; on 2026-11-27 the file
// became version 2 (the standard FNV-1a trailer), nothing else changed.
TEST(DefaultDecoderTest, IsTheShippedFileByteForByte) {
  const std::vector<uint8_t> bytes = ReadFileBytes(kModel);
  EXPECT_EQ(bytes.size(), 623054u);
  EXPECT_EQ(Fnv1a64(bytes.data(), bytes.size()), 0x3d58e1213d0ba822ull);
}

// Every bit of a random message set on 128 px held-out crops by pixel-space
// Adam, above 25 dB; no unmarked crop passes the verdict for that message,
// and each steered crop does.
TEST(DefaultDecoderTest, SteerableAndBalancedOnHeldOutPhotos) {
  std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(kModel, Device::kCpu, 48);
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  const std::vector<ImageRGB> crops = SamplePhotoCrops(photos, 128, 400, 17);
  std::mt19937 rng(29);
  Bits target(48);
  for (auto& b : target) b = rng() & 1;
  std::vector<ImageRGB> steered;
  for (int i = 0; i < 3; ++i) {
    SteerResult r =
        SteerPixels(*decoder, crops[i * 50], target, 400, 0.002, 0.5);
    EXPECT_EQ(r.bit_errors, 0) << i;
    EXPECT_GT(r.psnr, 25.0) << i;
    steered.push_back(std::move(r.image));
  }
  const DecoderBalance balance = MeasureBalance(*decoder, crops, target);
  EXPECT_EQ(balance.false_positives, 0);
  EXPECT_GT(balance.ones_fraction, 0.4);
  EXPECT_LT(balance.ones_fraction, 0.6);
  // No bit position is stuck: each reads 1 on 10-90% of the crops. (Over
  // crops of only 8 photos a bit's fraction moves in steps of about 1/8, by
  // which photos lean which way: these crops give 0.115-0.885, so the
  // corpus's 0.36-0.69 over 16 photos, docs/decoder_design.md, cannot be
  // asserted here; 0.2-0.8 fails.) The closest unmarked crop is far from the
  // verdict's budget (7 of 48 wrong).
  EXPECT_GE(balance.min_bit_ones, 0.1);
  EXPECT_LE(balance.max_bit_ones, 0.9);
  EXPECT_GE(balance.min_bit_errors, 12);
  // The positive case: each steered crop, which reads the claim, counts once
  // among the unmarked ones.
  for (size_t i = 0; i < steered.size(); ++i) {
    std::vector<ImageRGB> mixed(crops.begin() + 1, crops.begin() + 60);
    mixed.push_back(steered[i]);
    const DecoderBalance with_one = MeasureBalance(*decoder, mixed, target);
    EXPECT_EQ(with_one.false_positives, 1) << i;
    EXPECT_EQ(with_one.min_bit_errors, 0) << i;
    EXPECT_EQ(with_one.image_bits.back(), target) << i;
  }
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
