// Issue 29: decoding an image file must be decoding the same image in
// memory, in every command that reads image files. Renders of a model are
// written as PNG and as JPEG (quality 95) and read back through each path:
// decoder training's photo folder (LoadPhotoFolder, also make_decoder's and
// train_decoder's), `decoder_stats` on whole images, `detect`, and the
// workspace's training ground truth (Workspace::LoadView). With PNG every
// view must read exactly the bits the shipped decoder reads from the 8-bit
// render in memory; with JPEG within a measured bound, and every path the
// same bits as every other.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"
#include "plugin/workspace.h"
#include "tests/plugin/rendered_images.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/message.h"

namespace watergs {
namespace {

using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

// JPEG at quality 95 changes at most this many of a view's 48 bits (the
// logits nearest 0 flip). Measured on these 8 renders of 96x72: at most 1
// bit per view; the bound leaves room for another libjpeg's rounding.
constexpr int kJpeg95MaxBitFlips = 3;

Bits ReadBits(BitDecoder& decoder, const ImageRGB& image) {
  const std::vector<float> logits = decoder.Logits(image);
  Bits bits(logits.size());
  for (size_t i = 0; i < logits.size(); ++i) bits[i] = logits[i] > 0;
  return bits;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// File name -> the bits each reading path gets from the files of `folder`
// (PhotoFolder, decoder_stats, detect).
std::map<std::string, std::map<std::string, std::string>> BitsOfEveryPath(
    BitDecoder& decoder, const std::string& folder, const TempDir& dir) {
  std::map<std::string, std::map<std::string, std::string>> bits;
  std::vector<std::string> paths;
  const std::vector<cv::Mat> photos = LoadPhotoFolder(folder, &paths);
  EXPECT_EQ(photos.size(), paths.size());
  for (size_t i = 0; i < photos.size(); ++i) {
    bits[std::filesystem::path(paths[i]).filename().string()]["PhotoFolder"] =
        BitsToString(ReadBits(decoder, ToImageRGB(photos[i])));
  }
  const std::string stats_json = dir / "stats.json";
  const auto stats =
      RunCommand(WatergsBin() + " decoder_stats --decoder " + kDecoder +
                 " --image_path " + folder + " --json " + stats_json);
  EXPECT_EQ(stats.exit_code, 0) << stats.output;
  if (stats.exit_code == 0) {
    const nlohmann::json j = ReadJson(stats_json);
    for (const auto& image : j["per_image"]) {
      const std::string path = image["path"];
      bits[std::filesystem::path(path).filename().string()]["decoder_stats"] =
          image["bits"];
    }
  }
  const std::string detect_json = dir / "detect.json";
  const auto detect =
      RunCommand(WatergsBin() + " detect --decoder " + kDecoder +
                 " --image_path " + folder + " --json " + detect_json);
  EXPECT_EQ(detect.exit_code, 0) << detect.output;
  if (detect.exit_code == 0) {
    const nlohmann::json j = ReadJson(detect_json);
    for (const auto& image : j["views"]) {
      const std::string path = image["name"];
      bits[std::filesystem::path(path).filename().string()]["detect"] =
          image["bits"];
    }
  }
  return bits;
}

TEST(ImageReadingCli, EveryPathReadsAFileAsTheImageItHolds) {
  TempDir dir("image_reading_cli");
  testing::SyntheticModelOptions options;
  options.num_images = 8;
  options.width = 96;
  options.height = 72;
  GaussianModel model;
  WorkspaceOptions wo;
  wo.workspace_path =
      testing::MakeRenderedWorkspace(dir / "ws", options, &model);
  const Workspace workspace = Workspace::Open(wo);
  const std::vector<ImageRGB> renders = testing::RenderViews(model, workspace);
  const std::string png = dir / "png", jpg = dir / "jpg";
  CreateDirectories(png);
  CreateDirectories(jpg);
  std::unique_ptr<BitDecoder> decoder = LoadBitDecoder(kDecoder, Device::kCpu);
  std::map<std::string, std::string> expected_png, expected_jpg;
  for (size_t v = 0; v < renders.size(); ++v) {
    const std::string stem = "view_" + std::to_string(v);
    WriteImageFile(png + "/" + stem + ".png", renders[v]);
    WriteImageFile(jpg + "/" + stem + ".jpg", renders[v], "", 95);
    const ImageRGB quantised = testing::Quantise8(renders[v]);
    expected_png[stem + ".png"] = expected_jpg[stem + ".jpg"] =
        BitsToString(ReadBits(*decoder, quantised));
    // Training ground truth: the workspace's own PNG of this view (the same
    // render) decodes to exactly the 8-bit render.
    EXPECT_EQ(workspace.LoadView(v).data, quantised.data)
        << workspace.ViewName(v);
  }

  const auto png_bits = BitsOfEveryPath(*decoder, png, dir);
  ASSERT_EQ(png_bits.size(), renders.size());
  for (const auto& [name, by_path] : png_bits) {
    ASSERT_EQ(by_path.size(), 3u) << name;
    for (const auto& [path, bits] : by_path) {
      EXPECT_EQ(bits, expected_png[name]) << name << " read by " << path;
    }
  }
  const auto jpg_bits = BitsOfEveryPath(*decoder, jpg, dir);
  ASSERT_EQ(jpg_bits.size(), renders.size());
  int worst = 0;
  for (const auto& [name, by_path] : jpg_bits) {
    ASSERT_EQ(by_path.size(), 3u) << name;
    const std::string& first = by_path.begin()->second;
    for (const auto& [path, bits] : by_path) {
      EXPECT_EQ(bits, first) << name << " read by " << path;
      int flips = 0;
      for (size_t i = 0; i < bits.size(); ++i) {
        flips += bits[i] != expected_jpg[name][i];
      }
      worst = std::max(worst, flips);
    }
  }
  EXPECT_LE(worst, kJpeg95MaxBitFlips);
  std::printf("JPEG 95: at most %d of 48 bits flipped per view\n", worst);
}

}  // namespace
}  // namespace watergs
