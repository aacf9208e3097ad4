// `watergs make_decoder` and `watergs decoder_stats` end to end: a decoder
// made from photos loads and reads unmarked images without a false positive;
// the same command twice writes the same bytes; decoder_stats counts a steered
// image reading the claim as one false positive, in its line and its JSON;
// bad input is a one-line error naming the file or option, and writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <string>

#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"
#include "tests/plugin/rendered_workspace.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/message.h"

namespace watergs {
namespace {

using testing::CommandResult;
using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";
const std::string kShippedDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

// decoder_stats' figures: its second line's count and fewest bit errors,
// and its JSON.
struct StatsFigures {
  int false_positives = -1, min_bit_errors = -1;
  nlohmann::json json;
};

StatsFigures RunDecoderStats(const std::string& folder,
                             const std::string& message,
                             const std::string& json_path) {
  const CommandResult run =
      RunCommand(WatergsBin() + " decoder_stats --decoder " + kShippedDecoder +
                 " --image_path " + folder + " --message " + message +
                 " --json " + json_path);
  StatsFigures figures;
  EXPECT_EQ(run.exit_code, 0) << run.output;
  std::smatch m;
  const std::regex line(
      "would pass the verdict \\(p <= 1e-06, at most 7 of 48 bits wrong\\): "
      "([0-9]+); fewest bit errors seen ([0-9]+)");
  EXPECT_TRUE(std::regex_search(run.output, m, line)) << run.output;
  if (!m.empty()) {
    figures.false_positives = std::stoi(m[1]);
    figures.min_bit_errors = std::stoi(m[2]);
  }
  std::ifstream in(json_path);
  figures.json = nlohmann::json::parse(in, nullptr, false);
  EXPECT_FALSE(figures.json.is_discarded()) << json_path;
  return figures;
}

std::string MakeDecoderCommand(const std::string& output) {
  return WatergsBin() + " make_decoder --image_path " + kPhotos +
         " --validation_path " + kPhotos + " --output_path " + output +
         " --num_bits 16 --channels 48 --crop 64 --normalisation_crops 32"
         " --feature_crops 200 --balance_crops 50 --steer_images 1";
}

TEST(DecoderCli, MakeDecoderWritesALoadableReproducibleDecoder) {
  TempDir dir("decoder_cli");
  const CommandResult run = RunCommand(MakeDecoderCommand(dir / "a.bin") +
                                       " --json " + (dir / "a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("false positives at p <= 1e-6: 0"),
            std::string::npos)
      << run.output;
  EXPECT_EQ(LoadBitDecoder(dir / "a.bin", Device::kCpu, 16)->NumBits(), 16);
  EXPECT_TRUE(std::filesystem::exists(dir / "a.json"));
  ASSERT_EQ(RunCommand(MakeDecoderCommand(dir / "b.bin")).exit_code, 0);
  EXPECT_EQ(ReadFileBytes(dir / "a.bin"), ReadFileBytes(dir / "b.bin"));

  const CommandResult stats =
      RunCommand(WatergsBin() + " decoder_stats --decoder " + (dir / "a.bin") +
                 " --image_path " + kPhotos + " --crop 64 --crops 100");
  ASSERT_EQ(stats.exit_code, 0) << stats.output;
  EXPECT_NE(stats.output.find("100 crops"), std::string::npos) << stats.output;
  EXPECT_NE(stats.output.find("would pass the verdict"), std::string::npos);
}

// The positive case of the false-positive counter, end to end: the held-out
// photos read nothing close to a claim (0 counted, >= 12 bits wrong), and a
// copy of one of them steered to the claim, saved as an 8-bit PNG beside
// them, is counted once, in the printed line and in the JSON, with the
// claim's bits under its path.
TEST(DecoderCli, DecoderStatsCountsASteeredImageReadingTheClaim) {
  TempDir dir("decoder_stats_positive");
  std::mt19937 rng(41);
  Bits target(48);
  for (auto& b : target) b = rng() & 1;
  const std::string claim = "bits:" + BitsToString(target);

  const StatsFigures unmarked =
      RunDecoderStats(kPhotos, claim, dir / "unmarked.json");
  EXPECT_EQ(unmarked.false_positives, 0);
  EXPECT_GE(unmarked.min_bit_errors, 12);
  EXPECT_EQ(unmarked.json.value("images", -1), 8);
  EXPECT_EQ(unmarked.json.value("false_positives", -1), 0);
  EXPECT_EQ(unmarked.json.value("min_bit_errors", -1), unmarked.min_bit_errors);

  const std::string folder = dir / "photos";
  std::filesystem::copy(kPhotos, folder);
  std::vector<std::string> paths;
  const std::vector<cv::Mat> photos = LoadPhotoFolder(folder, &paths);
  ASSERT_EQ(photos.size(), 8u);
  std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(kShippedDecoder, Device::kCpu, 48);
  // A margin that survives the 8-bit rounding of the PNG.
  const SteerResult steered =
      SteerPixels(*decoder, ToImageRGB(photos[0]), target, 600, 0.002, 2.0);
  ASSERT_EQ(steered.bit_errors, 0);
  const std::string steered_path = folder + "/steered.png";
  WriteImageFile(steered_path, steered.image);
  ASSERT_EQ(BitsToString(
                MeasureBalance(*decoder, {ReadImageFile(steered_path)}, target)
                    .image_bits[0]),
            BitsToString(target));

  const StatsFigures mixed = RunDecoderStats(folder, claim, dir / "mixed.json");
  EXPECT_EQ(mixed.false_positives, 1);
  EXPECT_EQ(mixed.min_bit_errors, 0);
  EXPECT_EQ(mixed.json.value("images", -1), 9);
  EXPECT_EQ(mixed.json.value("false_positives", -1), 1);
  EXPECT_EQ(mixed.json.value("min_bit_errors", -1), 0);
  int reading_the_claim = 0;
  for (const auto& image : mixed.json.value("per_image", nlohmann::json())) {
    if (image.value("bits", "") != BitsToString(target)) continue;
    ++reading_the_claim;
    EXPECT_EQ(image.value("path", ""), steered_path);
  }
  EXPECT_EQ(reading_the_claim, 1);
}

TEST(DecoderCli, BadInputIsAOneLineErrorAndWritesNothing) {
  TempDir dir("decoder_cli_bad");
  const std::string out = dir / "d.bin";
  ExpectOneLineError(RunCommand(WatergsBin() + " make_decoder --image_path " +
                                (dir / "missing") + " --output_path " + out),
                     "missing");
  ExpectOneLineError(RunCommand(MakeDecoderCommand(out) + " --whiten_floor 0"),
                     "--whiten_floor");
  ExpectOneLineError(RunCommand(MakeDecoderCommand(out) + " --channels 8"),
                     "channels");
  // An output folder that does not exist is refused before the work.
  ExpectOneLineError(RunCommand(MakeDecoderCommand(dir / "no/such/d.bin")),
                     "d.bin");
  EXPECT_FALSE(std::filesystem::exists(out));
  // A file that is not a decoder.
  std::ofstream(dir / "garbage.bin") << "not a network file";
  ExpectOneLineError(
      RunCommand(WatergsBin() + " decoder_stats --decoder " +
                 (dir / "garbage.bin") + " --image_path " + kPhotos),
      "garbage.bin");
  ExpectOneLineError(
      RunCommand(WatergsBin() + " decoder_stats --decoder " +
                 (dir / "garbage.bin") + " --image_path " + kPhotos +
                 " --json " + (dir / "no/such/folder/s.json")),
      "s.json");
}

}  // namespace
}  // namespace watergs
