// `watergs make_decoder` and `watergs decoder_stats` end to end: a decoder
// made from photos loads and reads unmarked images without a false positive;
// the same command twice writes the same bytes; bad input is a one-line
// error naming the file or option, and writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "gaussian/file_util.h"
#include "tests/plugin/rendered_workspace.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/bit_decoder.h"

namespace watergs {
namespace {

using testing::CommandResult;
using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";

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
