// The paper's HiDDeN pair shipped in watermark/models/hidden_48.bin (not the
// default decoder: see default_decoder_test.cc): it loads, its encoder is
// invisible on held-out photos (tests/data/photos), its decoder finds no
// message in unmarked photos, and a corrupted or truncated copy is refused.
// It is under-trained (it reads 51.6% of its encoder's bits; training it is
// GPU-scale, docs/decoder_design.md), so no accuracy is asserted.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "tests/common/corrupt_copies.h"
#include "watermark/decoder.h"
#include "watermark/decoder_training.h"

namespace watergs {
namespace {

const std::string kModel =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/hidden_48.bin";
const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";
// The encoder's PSNR target of issue 4 for these photos (128x128, no noise).
constexpr double kTargetPsnr = 33.0;

// [-1,1] NCHW slot 0 -> ImageRGB in [0,1].
ImageRGB ToImage(const Tensor& t) {
  ImageRGB image(t.w, t.h);
  const size_t hw = t.PlaneSize();
  for (size_t p = 0; p < hw; ++p)
    for (int c = 0; c < 3; ++c)
      image.data[p * 3 + c] =
          (std::clamp(t.data[c * hw + p], -1.f, 1.f) + 1.f) / 2.f;
  return image;
}

// Bit accuracy of the shipped decoder on its own encoder's output, encoder
// PSNR, and accuracy on the unmarked covers, over the held-out photos.
struct ShippedFigures {
  double accuracy = 0, cover_accuracy = 0, psnr = 0;
};

ShippedFigures MeasureShippedDecoder() {
  auto model = LoadHiddenModel(kModel, true, 48);
  Decoder decoder = Decoder::Load(kModel, 48);
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  EXPECT_GE(photos.size(), 8u);
  std::mt19937 rng(2024);
  std::bernoulli_distribution coin(0.5);
  size_t correct = 0, cover_correct = 0, bits = 0;
  double psnr = 0;
  for (const cv::Mat& photo : photos) {
    Tensor cover(1, 3, photo.rows, photo.cols);
    PhotoToTensor(photo, 0, 0, 0, &cover);
    std::vector<float> message(48), signs(48);
    for (int i = 0; i < 48; ++i) {
      message[i] = coin(rng) ? 1.f : 0.f;
      signs[i] = 2 * message[i] - 1;
    }
    const ImageRGB marked =
        ToImage(model->encoder->Forward(cover, signs, false));
    const ImageRGB plain = ToImage(cover);
    double mse = 0;
    for (size_t i = 0; i < marked.data.size(); ++i)
      mse +=
          (marked.data[i] - plain.data[i]) * (marked.data[i] - plain.data[i]);
    psnr += -10 * std::log10(mse / marked.data.size());
    const std::vector<float> logits = decoder.Logits(marked);
    const std::vector<float> cover_logits = decoder.Logits(plain);
    for (int i = 0; i < 48; ++i) {
      correct += (logits[i] > 0) == (message[i] > 0.5f);
      cover_correct += (cover_logits[i] > 0) == (message[i] > 0.5f);
    }
    bits += 48;
  }
  ShippedFigures figures;
  figures.accuracy = double(correct) / bits;
  figures.cover_accuracy = double(cover_correct) / bits;
  figures.psnr = psnr / double(photos.size());
  return figures;
}

TEST(ShippedDecoderTest, EncoderIsInvisibleAndCoversCarryNoMessage) {
  const ShippedFigures figures = MeasureShippedDecoder();
  EXPECT_GE(figures.psnr, kTargetPsnr);
  // Unmarked photos carry no message: near chance against a random one.
  EXPECT_LT(figures.cover_accuracy, 0.7);
}

TEST(ShippedDecoderTest, RefusesCorruptedAndTruncatedCopies) {
  testing::ExpectCorruptCopiesRefused(
      kModel, [](const std::string& copy) { Decoder::Load(copy); });
}

}  // namespace
}  // namespace watergs
