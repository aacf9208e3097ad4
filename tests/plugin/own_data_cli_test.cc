// The README's commands for the user's own data, on a small case: an
// existing COLMAP workspace through `pipeline --workspace_path` (no
// reconstruct stage), and an existing splat through `embed --input_path
// --workspace_path` with nothing else but the message (the shipped decoder
// is the default); and the one-line refusals for a mismatched splat and for
// a pipeline given neither photos nor a workspace; and `train --init_path`
// refining an existing splat saved in its trainer's own frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "distortion/file_attacks.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

testing::SyntheticModelOptions Scene(uint32_t seed) {
  testing::SyntheticModelOptions options = testing::SmallSceneOptions();
  options.num_points = 300;
  options.width = 64;
  options.height = 48;
  options.seed = seed;
  return options;
}

TEST(OwnDataCli, PipelineOnAnExistingWorkspaceSkipsReconstruct) {
  TempDir dir("own_pipeline");
  const std::string ws = testing::MakeRenderedWorkspace(dir / "ws", Scene(3));
  const std::string out = dir / "out";
  const auto run = RunCommand(
      WatergsBin() + " pipeline --workspace_path " + ws +
      " --message text:MINE --output_path " + out +
      " --downscale 1 --iterations 30 --num_threads 2"
      " --embed_args '--iterations 4 --check_every 2 --check_views 2'");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("pipeline: 1/2 train"), std::string::npos)
      << run.output;
  EXPECT_EQ(run.output.find("reconstruct"), std::string::npos) << run.output;
  EXPECT_TRUE(std::filesystem::is_regular_file(out + "/watermarked.ply"));
  EXPECT_TRUE(std::filesystem::is_regular_file(out + "/report.html"));
  EXPECT_FALSE(std::filesystem::is_regular_file(
      out + "/workspace/sparse/0/cameras.txt"));

  ExpectOneLineError(RunCommand(WatergsBin() +
                                " pipeline --message text:MINE "
                                "--output_path " +
                                std::string(dir / "none")),
                     "give --image_path (a folder of photos) or "
                     "--workspace_path");
}

TEST(OwnDataCli, EmbedsAnExistingSplatWithTheShippedDecoder) {
  TempDir dir("own_splat");
  GaussianModel truth;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", Scene(3), &truth);
  // Saved by "another trainer": its own frame, its own layout.
  ApplySimilarity(ParseSimilarity("40,0.3,-1,2,0.25,1,2,0.5"), &truth);
  const std::string mine =
      testing::WriteAsciiPlyWithNormals(dir / "mine.ply", truth);
  const std::string marked = dir / "mine_wm.ply";
  const auto run = RunCommand(
      WatergsBin() + " embed --input_path " + mine + " --workspace_path " + ws +
      " --message text:MINE --output_path " + marked +
      " --iterations 4 --check_every 2 --check_views 2 --num_threads 2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("48-bit message"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("aligned to the workspace"), std::string::npos)
      << run.output;
  EXPECT_EQ(ReadPly(marked).model.size(), truth.size());

  // Another scene's splat: refused before any work, naming the file.
  GaussianModel other;
  testing::MakeRenderedWorkspace(dir / "other", Scene(11), &other);
  const std::string foreign =
      testing::WriteAsciiPlyWithNormals(dir / "foreign.ply", other);
  const auto refused = RunCommand(
      WatergsBin() + " embed --input_path " + foreign + " --workspace_path " +
      ws + " --message text:MINE --output_path " +
      std::string(dir / "foreign_wm.ply") + " --iterations 4");
  ExpectOneLineError(refused, foreign +
                                  ": does not match the workspace's "
                                  "photos");
  EXPECT_FALSE(
      std::filesystem::is_regular_file(std::string(dir / "foreign_wm.ply")));
}

// The bonsai refinement's path (train at --downscale 4, refine at full size)
// on a small case: a splat saved by "another trainer" in its own frame is
// aligned, trained in the workspace's frame from where it stood (not from
// the SfM points), and one of another SH degree is refused in one line.
TEST(OwnDataCli, TrainRefinesAnExistingSplatFromItsOwnFrame) {
  TempDir dir("own_refine");
  GaussianModel truth;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", Scene(3), &truth);
  GaussianModel moved = truth;
  ApplySimilarity(ParseSimilarity("40,0.3,-1,2,0.25,1,2,0.5"), &moved);
  const std::string mine =
      testing::WriteAsciiPlyWithNormals(dir / "mine.ply", moved);
  const std::string common = " --workspace_path " + ws +
                             " --split train --iterations 1 --num_threads 2"
                             " --test_iterations 1";
  const std::string refined = dir / "refined";
  const auto run =
      RunCommand(WatergsBin() + " train --init_path " + mine +
                 " --sh_degree 1 --output_path " + refined + common);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("aligned to the workspace"), std::string::npos)
      << run.output;
  const GaussianModel out = ReadPly(refined + "/point_cloud.ply").model;
  ASSERT_EQ(out.size(), truth.size());
  double worst = 0;
  for (size_t i = 0; i < out.means.size(); ++i) {
    worst = std::max(worst, std::abs(double(out.means[i]) - truth.means[i]));
  }
  EXPECT_LT(worst, 0.01) << "the model is not back in the workspace's frame";

  // From the SfM points the same iteration scores far lower.
  const std::string from_points = dir / "from_points";
  const auto sfm = RunCommand(WatergsBin() + " train --sh_degree 1" +
                              " --output_path " + from_points + common);
  ASSERT_EQ(sfm.exit_code, 0) << sfm.output;
  const auto psnr = [](const std::string& folder) {
    std::ifstream in(folder + "/report.json");
    return nlohmann::json::parse(in)["psnr"].get<double>();
  };
  EXPECT_GT(psnr(refined), psnr(from_points) + 5.0)
      << psnr(refined) << " vs " << psnr(from_points);

  ExpectOneLineError(
      RunCommand(WatergsBin() + " train --init_path " + mine +
                 " --output_path " + std::string(dir / "sh3") + common),
      mine + ": has SH degree 1, --sh_degree is 3: pass --sh_degree 1");
  EXPECT_FALSE(std::filesystem::exists(std::string(dir / "sh3")));
}

}  // namespace
}  // namespace watergs
