// `watergs make_decoder`: builds the default universal decoder, a whitened
// random-feature network (watermark/feature_decoder.h), from a folder of
// photos in seconds, and measures it on held-out photos: balance and false
// positives on unmarked crops, steerability by pixel-space Adam. The
// paper's HiDDeN decoder is `train_decoder` (GPU-scale training).
#include <fstream>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/network_file.h"
#include "watermark/verification.h"

namespace {

using watergs::Fail;

struct HeldOutFigures {
  watergs::DecoderBalance balance;
  int steered = 0, steer_errors = 0, steer_steps = 0;
  double steer_psnr = 0;
};

HeldOutFigures MeasureHeldOut(watergs::BitDecoder& decoder,
                              const std::vector<cv::Mat>& photos, int crop,
                              int balance_crops, int steer_images,
                              uint32_t seed) {
  HeldOutFigures figures;
  const int bits = decoder.NumBits();
  // A fixed claimed message (the false-positive count's), independent of
  // the decoder's seed.
  std::mt19937 message_rng(12345);
  watergs::Bits claimed(bits);
  for (auto& b : claimed) b = message_rng() & 1;
  figures.balance = watergs::MeasureBalance(
      decoder,
      watergs::SamplePhotoCrops(photos, crop, balance_crops, seed + 100),
      claimed);
  const std::vector<watergs::ImageRGB> steer_crops =
      watergs::SamplePhotoCrops(photos, crop, steer_images, seed + 200);
  for (const watergs::ImageRGB& image : steer_crops) {
    watergs::Bits target(bits);
    for (auto& b : target) b = message_rng() & 1;
    const watergs::SteerResult r =
        watergs::SteerPixels(decoder, image, target, 500, 0.002, 0.5);
    figures.steered++;
    figures.steer_errors += r.bit_errors;
    figures.steer_steps += r.steps;
    figures.steer_psnr += r.psnr;
  }
  if (figures.steered) {
    figures.steer_psnr /= figures.steered;
    figures.steer_steps /= figures.steered;
  }
  return figures;
}

int RunMakeDecoder(int argc, char** argv) {
  watergs::FeatureCalibrationOptions options;
  std::string image_path, validation_path, output_path, json_path;
  int seed = int(options.seed);
  int balance_crops = 1000, steer_images = 4;
  watergs::OptionParser parser(
      "make_decoder",
      "Builds WATER-GS's default universal decoder: random features whitened "
      "on photos (no training; seconds). --validation_path measures balance, "
      "false positives and steerability on held-out photos.");
  parser.AddRequired("image_path", &image_path,
                     "folder of calibration photos (jpg/png), e.g. "
                     "make_photo_corpus.sh's train/");
  parser.AddRequired("output_path", &output_path, "decoder weights to write");
  parser.Add("validation_path", &validation_path,
             "folder of held-out photos to measure the decoder on");
  parser.Add("json", &json_path, "write the figures as JSON here");
  parser.Add("num_bits", &options.config.num_bits, "message length L");
  parser.Add("channels", &options.config.channels, "random feature channels");
  parser.Add("pool", &options.config.pool,
             "average pooling of the image before the features");
  parser.Add("kernel", &options.config.kernel, "convolution kernel side");
  parser.Add("highpass", &options.config.highpass,
             "0: the features read the pooled image; r: its residual (minus "
             "its (2r+1)^2 box mean), blind to smooth shading");
  parser.Add("crop", &options.crop, "side of the calibration crops");
  parser.Add("normalisation_crops", &options.normalisation_crops,
             "crops that standardise the convolution");
  parser.Add("feature_crops", &options.feature_crops,
             "crops for the features' mean and covariance");
  parser.Add("whiten_floor", &options.whiten_floor,
             "eigenvalue floor, relative to the mean eigenvalue");
  parser.Add("steerable_subspace", &options.steerable_subspace,
             "0: logits read random whitened directions; K: random "
             "directions within the K most steerable ones");
  parser.Add("steering_crops", &options.steering_crops,
             "Photo crops the steerable directions are found on");
  parser.Add("calibration_blur", &options.calibration_blur,
             "0: calibrate on the photos as they are; S: each calibration "
             "crop blurred by a Gaussian of sigma uniform in [0, S] pixels "
             "(render-like: renders are softer than photos)");
  parser.Add("logit_scale", &options.logit_scale,
             "logit standard deviation on the calibration crops");
  parser.Add("balance_crops", &balance_crops,
             "held-out crops for the balance and false-positive figures");
  parser.Add("steer_images", &steer_images,
             "held-out crops steered to random messages");
  parser.Add("seed", &seed, "random seed");
  if (!parser.Parse(argc, argv)) return 0;
  options.seed = uint32_t(seed);
  const int bits = options.config.num_bits;
  if (bits < 8 || bits > 256) Fail("--num_bits must be in [8, 256]");
  if (options.crop < 16 || options.crop > 1024)
    Fail("--crop must be in [16, 1024]");
  if (options.normalisation_crops < 1 || options.feature_crops < 1 ||
      balance_crops < 2 || steer_images < 0)
    Fail(
        "--normalisation_crops and --feature_crops must be positive, "
        "--balance_crops at least 2");
  if (!(options.whiten_floor > 0 && options.whiten_floor < 1))
    Fail("--whiten_floor must be in (0, 1)");
  if (!(options.logit_scale > 0 && options.logit_scale < 1e3))
    Fail("--logit_scale must be in (0, 1000)");
  if (!(options.calibration_blur >= 0 && options.calibration_blur <= 64))
    Fail("--calibration_blur must be in [0, 64] pixels");
  // Refuse before the work: an output that is an input photo folder.
  if (watergs::SamePath(output_path, image_path))
    Fail("--output_path " + output_path + " is the photo folder");
  watergs::CheckOutputFile(output_path);
  if (!json_path.empty()) watergs::CheckOutputFile(json_path);

  const std::vector<cv::Mat> photos = watergs::LoadPhotoFolder(image_path);
  watergs::FeatureCalibrationReport report;
  std::unique_ptr<watergs::FeatureNet> net =
      watergs::CalibrateFeatureDecoder(photos, options, &report);
  std::cout << std::fixed << std::setprecision(3) << "calibrated on "
            << options.feature_crops << " crops of " << report.photos_used
            << " photos in " << report.seconds
            << " s; feature covariance eigenvalues " << std::scientific
            << std::setprecision(3) << report.max_eigenvalue << " .. "
            << report.min_eigenvalue << " (" << report.floored_eigenvalues
            << " raised to the floor)\n"
            << std::fixed;
  const watergs::NetworkFile file = watergs::FeatureNetToFile(*net);
  watergs::WriteNetworkFile(output_path, file);
  const std::string bytes = watergs::SerializeNetworkFile(file);
  std::cout << "wrote " << output_path << " (" << bytes.size()
            << " bytes, FNV-1a " << std::hex
            << watergs::Fnv1a64(reinterpret_cast<const uint8_t*>(bytes.data()),
                                bytes.size())
            << std::dec << ")\n";

  std::ostringstream json;
  json << std::setprecision(6) << "{\"num_bits\": " << bits
       << ", \"channels\": " << options.config.channels
       << ", \"pool\": " << options.config.pool
       << ", \"kernel\": " << options.config.kernel
       << ", \"highpass\": " << options.config.highpass
       << ", \"calibration_blur\": " << options.calibration_blur
       << ", \"photos\": " << report.photos_used
       << ", \"feature_crops\": " << options.feature_crops
       << ", \"floored_eigenvalues\": " << report.floored_eigenvalues;
  if (!validation_path.empty()) {
    watergs::FeatureDecoder decoder(std::move(net));
    const HeldOutFigures f =
        MeasureHeldOut(decoder, watergs::LoadPhotoFolder(validation_path),
                       options.crop, balance_crops, steer_images, options.seed);
    const watergs::DecoderBalance& b = f.balance;
    std::cout << std::setprecision(3) << "held-out unmarked crops: " << b.images
              << ", fraction of 1-bits " << b.ones_fraction << " (per bit "
              << b.min_bit_ones << " .. " << b.max_bit_ones
              << "), mean |correlation| between bits " << b.mean_abs_correlation
              << ", false positives at p <= 1e-6: " << b.false_positives
              << " (fewest bit errors " << b.min_bit_errors << "/" << bits
              << ", threshold " << watergs::MaxErrorsForPresence(bits, 1e-6)
              << ")\n";
    if (f.steered)
      std::cout << "steering " << f.steered
                << " held-out crops (pixel Adam, lr 0.002, margin 0.5): "
                << f.steer_errors << " bit errors of " << f.steered * bits
                << " at " << std::setprecision(2) << f.steer_psnr
                << " dB mean PSNR, " << f.steer_steps << " steps on average\n";
    json << ", \"heldout_crops\": " << b.images
         << ", \"ones_fraction\": " << b.ones_fraction
         << ", \"min_bit_ones\": " << b.min_bit_ones
         << ", \"max_bit_ones\": " << b.max_bit_ones
         << ", \"mean_abs_correlation\": " << b.mean_abs_correlation
         << ", \"false_positives\": " << b.false_positives
         << ", \"min_bit_errors\": " << b.min_bit_errors
         << ", \"steered\": " << f.steered
         << ", \"steer_bit_errors\": " << f.steer_errors
         << ", \"steer_psnr\": " << f.steer_psnr
         << ", \"steer_steps\": " << f.steer_steps;
  }
  json << ", \"provenance\": " << watergs::Provenance(argc, argv).dump()
       << "}\n";
  if (!json_path.empty()) watergs::AtomicWriteFile(json_path, json.str());
  return 0;
}

}  // namespace

WATERGS_COMMAND(make_decoder,
                "Builds the default universal decoder (whitened random "
                "features) from photos",
                RunMakeDecoder);
