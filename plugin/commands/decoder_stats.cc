// `watergs decoder_stats`: how a decoder reads unmarked images (photos, or
// renders of an unmarked model): fraction of 1-bits, correlation between
// bits, and how many images would pass the verdict for a claimed message,
// the false positives an owner's p-value assumes away.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/image_reading.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace {

using watergs::Fail;

int RunDecoderStats(int argc, char** argv) {
  std::string decoder_path, image_path, message, json_path;
  int crop = 0, crops = 1000, seed = 0;
  double present_p = watergs::VerificationThresholds().present_p;
  watergs::OptionParser parser(
      "decoder_stats",
      "Decodes unmarked images (whole, or random square crops) and reports "
      "the fraction of 1-bits, the mean |correlation| between bits and how "
      "many images the verdict would call watermarked for a claimed message.");
  decoder_path = watergs::ShippedDecoderPath();
  parser.Add("decoder", &decoder_path, watergs::kDecoderHelp);
  parser.AddRequired("image_path", &image_path,
                     "Folder of unmarked images (jpg/png)");
  parser.Add("message", &message,
             "Claimed message (default: a fixed random one)");
  parser.Add("crop", &crop, "Side of random crops (0: whole images)");
  parser.Add("crops", &crops, "Number of random crops (with --crop)");
  parser.Add("false_positive_rate", &present_p,
             "p-value at or below which the verdict says present");
  parser.Add("seed", &seed, "Seed of the crops");
  parser.Add("json", &json_path,
             "Write the figures as JSON here (whole images: also each "
             "file's bits)");
  if (!parser.Parse(argc, argv)) return 0;
  if (crop < 0 || (crop > 0 && crops < 2))
    Fail("--crop must be >= 0 and --crops >= 2");
  if (!(present_p > 0 && present_p < 0.01))
    Fail("--false_positive_rate must be in (0, 0.01)");
  if (!json_path.empty()) watergs::CheckOutputFile(json_path);
  std::unique_ptr<watergs::BitDecoder> decoder =
      watergs::LoadBitDecoder(decoder_path, parser.device());
  const int bits = decoder->NumBits();
  watergs::Bits claimed(bits);
  if (message.empty()) {
    std::mt19937 rng(12345);
    for (auto& b : claimed) b = rng() & 1;
  } else {
    claimed = watergs::ParseMessage(message, bits);
  }
  std::vector<std::string> paths;
  const std::vector<cv::Mat> photos =
      watergs::LoadPhotoFolder(image_path, &paths);
  std::vector<watergs::ImageRGB> images;
  if (crop > 0) {
    images = watergs::SamplePhotoCrops(photos, crop, crops, uint32_t(seed));
  } else {
    for (const cv::Mat& p : photos) images.push_back(watergs::ToImageRGB(p));
  }
  const watergs::DecoderBalance b =
      watergs::MeasureBalance(*decoder, images, claimed, present_p);
  std::cout << std::fixed << std::setprecision(3)
            << "decoder_stats: " << b.images
            << (crop > 0 ? " crops" : " images") << ", fraction of 1-bits "
            << b.ones_fraction << " (per bit " << b.min_bit_ones << " .. "
            << b.max_bit_ones << "), mean |correlation| between bits "
            << b.mean_abs_correlation
            << "\ndecoder_stats: would pass the verdict (p <= "
            << std::defaultfloat << present_p << std::fixed << ", at most "
            << watergs::MaxErrorsForPresence(bits, present_p) << " of " << bits
            << " bits wrong): " << b.false_positives
            << "; fewest bit errors seen " << b.min_bit_errors << "\n";
  // The lean (issue 52): what the images read per bit without a watermark.
  double abs_mean = 0, largest = 0, spread = 0;
  for (int k = 0; k < bits; ++k) {
    abs_mean += std::abs(b.bit_mean[k]) / bits;
    largest = std::max(largest, std::abs(b.bit_mean[k]));
    spread += b.bit_std[k] / bits;
  }
  std::cout << std::setprecision(2) << "decoder_stats: lean: mean logit per "
            << "bit |mean| " << abs_mean << " (largest " << largest
            << "), spread from image to image " << spread << "\n";
  if (!json_path.empty()) {
    std::ostringstream json;
    json << std::setprecision(6) << "{\"images\": " << b.images
         << ", \"ones_fraction\": " << b.ones_fraction
         << ", \"min_bit_ones\": " << b.min_bit_ones
         << ", \"max_bit_ones\": " << b.max_bit_ones
         << ", \"mean_abs_correlation\": " << b.mean_abs_correlation
         << ", \"false_positives\": " << b.false_positives
         << ", \"min_bit_errors\": " << b.min_bit_errors
         << ", \"bit_mean\": " << nlohmann::json(b.bit_mean).dump()
         << ", \"bit_std\": " << nlohmann::json(b.bit_std).dump();
    if (crop == 0) {
      // Whole images: what each file reads, by path.
      nlohmann::json per_image = nlohmann::json::array();
      for (size_t i = 0; i < paths.size(); ++i) {
        per_image.push_back({{"path", paths[i]},
                             {"bits", watergs::BitsToString(b.image_bits[i])}});
      }
      json << ", \"per_image\": " << per_image.dump();
    }
    json << ", \"provenance\": " << watergs::Provenance(argc, argv).dump()
         << "}\n";
    watergs::AtomicWriteFile(json_path, json.str());
  }
  return 0;
}

}  // namespace

WATERGS_COMMAND(decoder_stats,
                "Balance and false positives of a decoder on unmarked images",
                RunDecoderStats);
