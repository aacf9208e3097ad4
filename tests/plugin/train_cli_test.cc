// CLI tests of `watergs train` and `watergs render` on a small synthetic
// COLMAP workspace whose images are rendered from Gaussians at its points.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "gaussian/formats/ply_io.h"
#include "gaussian/point_init.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

// WS/sparse/0 (8 pinhole views, 64x48) and rendered WS/images.
std::string MakeWorkspace(const TempDir& dir) {
  testing::SyntheticModelOptions options;
  options.num_images = 8;
  options.num_points = 200;
  return testing::MakeRenderedWorkspace(dir / "ws", options);
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST(TrainCli, TrainsWritesOutputsAndResumes) {
  TempDir dir("train_cli");
  const std::string ws = MakeWorkspace(dir);
  const std::string out = dir / "out";
  const std::string args =
      " --workspace_path " + ws + " --output_path " + out +
      " --iterations 30 --split train --checkpoint_every 15 "
      "--sh_degree 1 --seed 3 --num_threads 2 "
      "--test_iterations 15";
  const auto run = RunCommand(WatergsBin() + " train" + args);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("PSNR"), std::string::npos) << run.output;

  const PlyData ply = ReadPly(out + "/point_cloud.ply");
  EXPECT_EQ(ply.model.sh_degree, 1);
  EXPECT_GT(ply.model.size(), 0u);
  const auto cameras = ReadJson(out + "/cameras.json");
  ASSERT_EQ(cameras.size(), 8u);
  for (const char* key : {"id", "img_name", "width", "height", "position",
                          "rotation", "fx", "fy"}) {
    EXPECT_TRUE(cameras[0].contains(key)) << key;
  }
  EXPECT_EQ(cameras[0]["rotation"].size(), 3u);
  const auto report = ReadJson(out + "/report.json");
  EXPECT_EQ(report["metrics_split"], "test");
  EXPECT_EQ(report["num_metric_views"], 1);  // views 0 of 8
  EXPECT_GT(report["psnr"].get<double>(), 10.0);
  EXPECT_EQ(report["iterations"], 30);
  std::ifstream log(out + "/train_log.jsonl");
  std::string line, last;
  bool saw_test = false;
  while (std::getline(log, line)) {
    const auto j = nlohmann::json::parse(line);
    saw_test |= j.contains("test_psnr");
    last = line;
  }
  EXPECT_TRUE(saw_test);
  EXPECT_EQ(nlohmann::json::parse(last)["iteration"], 30);

  // Resuming a finished run changes nothing.
  const auto before = ReadFileBytes(out + "/point_cloud.ply");
  const auto resumed = RunCommand(WatergsBin() + " train" + args + " --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_EQ(before, ReadFileBytes(out + "/point_cloud.ply"));

  // Render the held-out view.
  const std::string renders = dir / "renders";
  const auto render = RunCommand(WatergsBin() + " render --input_path " + out +
                                 "/point_cloud.ply --workspace_path " + ws +
                                 " --output_path " + renders + " --split test");
  ASSERT_EQ(render.exit_code, 0) << render.output;
  EXPECT_NE(render.output.find("PSNR"), std::string::npos);
  int pngs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(renders)) {
    pngs += entry.path().extension() == ".png";
  }
  EXPECT_EQ(pngs, 1);
}

TEST(TrainCli, BadInputGivesOneLineErrors) {
  TempDir dir("train_cli_bad");
  const std::string bin = WatergsBin();
  struct Case {
    std::string args, needle;
  };
  const Case cases[] = {
      {" train --workspace_path " + dir.path() + "/missing --output_path " +
           dir.path() + "/o",
       "missing"},
      {" train --workspace_path x --output_path y --background pink",
       "--background"},
      {" train --workspace_path x --output_path y --iterations 0",
       "--iterations"},
      {" train --workspace_path x --output_path y --sh_degree 4",
       "--sh_degree"},
      {" train --workspace_path x --output_path y --moment_precision fp8",
       "--moment_precision"},
      {" train --workspace_path x --output_path " + dir.path() + "/o2 --resume",
       "no checkpoint"},
      {" render --input_path " + dir.path() +
           "/none.ply --workspace_path x --output_path y",
       "none.ply"},
  };
  for (const Case& c : cases) {
    const auto r = RunCommand(bin + c.args);
    EXPECT_EQ(r.exit_code, 1) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.needle), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1)
        << r.output;
  }
}

}  // namespace
}  // namespace watergs
