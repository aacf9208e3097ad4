// Against the real COLMAP 3.8 binary (`colmap` on PATH, installed by
// scripts/install_deps.sh): on synthetic models it has never seen (every
// camera model, one and several cameras, .bin and .txt), `watergs
// model_info` prints the figures `colmap model_analyzer` prints, and
// `watergs model_converter` writes the bytes `colmap model_converter` writes.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/workspace.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

std::string Colmap() { return "QT_QPA_PLATFORM=offscreen colmap"; }

std::string FileText(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  return std::string(bytes.begin(), bytes.end());
}

// The model_analyzer lines ("Cameras: 3", ..., "Mean reprojection error:
// 0.5px") found in a command's output, in order.
std::string SummaryLines(const std::string& output) {
  static const char* kLabels[] = {"Cameras:",
                                  "Images:",
                                  "Registered images:",
                                  "Points:",
                                  "Observations:",
                                  "Mean track length:",
                                  "Mean observations per image:",
                                  "Mean reprojection error:"};
  std::istringstream in(output);
  std::string line, lines;
  while (std::getline(in, line)) {
    for (const char* label : kLabels) {
      if (line.rfind(label, 0) == 0) lines += line + "\n";
    }
  }
  return lines;
}

class ColmapCompat : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const testing::CommandResult help = testing::RunCommand(Colmap() + " -h");
    ASSERT_NE(help.output.find("COLMAP 3.8"), std::string::npos)
        << "colmap 3.8 must be on PATH (scripts/install_deps.sh --tests): "
        << help.output;
  }

  // Writes the model in `format`, then checks model_info against
  // model_analyzer and both converters' BIN and TXT outputs byte for byte.
  void Check(const testing::SyntheticModelOptions& options, ModelFormat format,
             std::vector<std::string> output_types = {"BIN", "TXT"}) {
    const std::string label =
        "model ids " + std::to_string(options.model_ids.size()) + " first " +
        std::to_string(options.model_ids[0]) +
        (format == ModelFormat::kBinary ? " BIN" : " TXT");
    const std::string input = dir_ / "input";
    fs::remove_all(dir_.path());
    WriteReconstruction(testing::MakeSyntheticReconstruction(options), input,
                        format);
    const testing::CommandResult ours = testing::RunCommand(
        testing::WatergsBin() + " model_info --sparse_path " + input);
    const testing::CommandResult theirs =
        testing::RunCommand(Colmap() + " model_analyzer --path " + input);
    ASSERT_EQ(ours.exit_code, 0) << label << ours.output;
    ASSERT_EQ(theirs.exit_code, 0) << label << theirs.output;
    const std::string summary = SummaryLines(theirs.output);
    EXPECT_NE(summary.find("Mean reprojection error:"), std::string::npos)
        << theirs.output;
    EXPECT_EQ(SummaryLines(ours.output), summary) << label;
    for (const std::string& type : output_types) {
      const std::string ext = type == "BIN" ? ".bin" : ".txt";
      const std::string colmap_out = dir_ / ("colmap_" + ext.substr(1));
      const std::string our_out = dir_ / ("ours_" + ext.substr(1));
      fs::create_directories(colmap_out);
      const testing::CommandResult converted = testing::RunCommand(
          Colmap() + " model_converter --input_path " + input +
          " --output_path " + colmap_out + " --output_type " + type);
      ASSERT_EQ(converted.exit_code, 0) << converted.output;
      const testing::CommandResult ours_converted = testing::RunCommand(
          testing::WatergsBin() + " model_converter --sparse_path " + input +
          " --output_path " + our_out + " --output_type " + type);
      ASSERT_EQ(ours_converted.exit_code, 0) << ours_converted.output;
      for (const char* name : {"cameras", "images", "points3D"}) {
        const std::string file = name + ext;
        EXPECT_EQ(FileText(our_out + "/" + file),
                  FileText(colmap_out + "/" + file))
            << label << " " << file;
      }
    }
  }

  testing::TempDir dir_{"colmap_compat"};
};

TEST_F(ColmapCompat, EveryCameraModelAloneBinAndTxt) {
  for (int model_id = 0; model_id < 11; ++model_id) {
    testing::SyntheticModelOptions options;
    options.model_ids = {model_id};
    options.num_images = 5;
    options.num_points = 60;
    options.seed = 10 + model_id;
    // Converted to the other format: BIN -> TXT is the must-match case.
    if (model_id % 2) {
      Check(options, ModelFormat::kText, {"BIN"});
    } else {
      Check(options, ModelFormat::kBinary, {"TXT"});
    }
  }
}

TEST_F(ColmapCompat, SeveralCamerasAllModels) {
  testing::SyntheticModelOptions options;
  options.model_ids = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  options.num_images = 30;
  options.num_points = 1000;
  Check(options, ModelFormat::kBinary);
  options.seed = 2;
  Check(options, ModelFormat::kText);
}

TEST_F(ColmapCompat, ModelWithoutPoints) {
  testing::SyntheticModelOptions options;
  options.model_ids = {2, 4};
  options.num_points = 0;
  Check(options, ModelFormat::kBinary);
}

// Hand-written text: unnormalized quaternions (COLMAP normalizes on read and
// on write), images without keypoints, a point without error, one without
// observations, -0 and denormal-range numbers.
TEST_F(ColmapCompat, HandWrittenTextConvertsLikeColmap) {
  const std::string input = dir_ / "hand";
  fs::create_directories(input);
  AtomicWriteFile(input + "/cameras.txt", "1 FOV 10 8 9 9.5 5 4 0.7\n");
  AtomicWriteFile(input + "/images.txt",
                  "3 0.9 0.1 0.2 0.3 0 0 1 1 x.png\n\n"
                  "4 0.3333 0.7777 0.123456789 0.987654321 1e-3 0 1 1 y.png\n"
                  "1.25 2.5 8 3 4 -1\n"
                  "5 2 3 5 7 0 0 1 1 z.png\n\n");
  AtomicWriteFile(input + "/points3D.txt",
                  "8 0.1 0.2 3 1 2 3 -1 4 0\n9 -0.0 1e-300 2 0 0 0 0.5\n");
  for (const char* type : {"TXT", "BIN"}) {
    const std::string theirs = dir_ / ("colmap_" + std::string(type));
    const std::string ours = dir_ / ("ours_" + std::string(type));
    fs::create_directories(theirs);
    ASSERT_EQ(testing::RunCommand(Colmap() + " model_converter --input_path " +
                                  input + " --output_path " + theirs +
                                  " --output_type " + type)
                  .exit_code,
              0);
    ASSERT_EQ(testing::RunCommand(
                  testing::WatergsBin() + " model_converter --sparse_path " +
                  input + " --output_path " + ours + " --output_type " + type)
                  .exit_code,
              0);
    const std::string ext = type[0] == 'T' ? ".txt" : ".bin";
    for (const char* name : {"cameras", "images", "points3D"}) {
      EXPECT_EQ(FileText(ours + "/" + name + ext),
                FileText(theirs + "/" + name + ext))
          << name << ext;
    }
  }
}

TEST_F(ColmapCompat, ModelInfoStepsIntoWorkspaceSparse0) {
  testing::SyntheticModelOptions options;
  options.model_ids = {8, 3};
  WriteReconstruction(testing::MakeSyntheticReconstruction(options),
                      dir_ / "ws/sparse/0", ModelFormat::kText);
  const testing::CommandResult ours = testing::RunCommand(
      testing::WatergsBin() + " model_info --sparse_path " + dir_ / "ws");
  const testing::CommandResult theirs = testing::RunCommand(
      Colmap() + " model_analyzer --path " + dir_ / "ws/sparse/0");
  ASSERT_EQ(ours.exit_code, 0) << ours.output;
  EXPECT_NE(SummaryLines(theirs.output), "");
  EXPECT_EQ(SummaryLines(ours.output), SummaryLines(theirs.output));
}

// The embedded demo scene (datasets_scripts/demo_scene: images/ + sparse/0,
// reconstructed by the real COLMAP) opens as a Workspace whose figures match
// model_analyzer's.
TEST_F(ColmapCompat, DemoSceneWorkspaceMatchesModelAnalyzer) {
  const std::string scene =
      std::string(WATERGS_SOURCE_DIR) + "/datasets_scripts/demo_scene";
  if (!fs::exists(scene + "/sparse/0")) {
    GTEST_SKIP() << "demo scene not generated (datasets_scripts/"
                    "make_demo_scene.sh)";
  }
  const testing::CommandResult ours = testing::RunCommand(
      testing::WatergsBin() + " model_info --sparse_path " + scene);
  const testing::CommandResult theirs = testing::RunCommand(
      Colmap() + " model_analyzer --path " + scene + "/sparse/0");
  ASSERT_EQ(ours.exit_code, 0) << ours.output;
  ASSERT_EQ(theirs.exit_code, 0) << theirs.output;
  EXPECT_EQ(SummaryLines(ours.output), SummaryLines(theirs.output));
  WorkspaceOptions options;
  options.workspace_path = scene;
  const Workspace workspace = Workspace::Open(options);
  EXPECT_NE(SummaryLines(theirs.output)
                .find("Registered images: " +
                      std::to_string(workspace.NumViews()) + "\n"),
            std::string::npos);
  const ImageRGB image = workspace.LoadView(workspace.NumViews() - 1);
  const RenderCamera camera = workspace.ViewCamera(workspace.NumViews() - 1);
  EXPECT_EQ(image.width, camera.width);
  EXPECT_EQ(image.height, camera.height);
  EXPECT_GT(workspace.SceneExtent(), 0);
}

}  // namespace
}  // namespace watergs
