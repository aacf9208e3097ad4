// CLI tests of the interface the commands share: one --sparse_path option
// everywhere (train's old --input_path kept as an alias), images optional
// where no ground truth is needed, `watergs help <command>`, --version,
// defaults printed as written, the message formats and their limit, and
// errors that name the right option or file in readable text.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "gaussian/file_util.h"
#include "gaussian/ply_io.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

// A small rendered workspace, its model as a PLY and a tiny decoder.
struct Scene {
  std::string ws, ply, decoder;
};

Scene MakeScene(const TempDir& dir) {
  GaussianModel truth;
  Scene s;
  s.ws = testing::MakeRenderedWorkspace(dir / "ws",
                                        testing::SmallSceneOptions(), &truth);
  s.ply = dir / "model.ply";
  WritePly(s.ply, truth);
  s.decoder = testing::WriteTinyDecoder(dir / "decoder.bin");
  return s;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// LPIPS weights missing at the default path (relative to the current
// folder) skip LPIPS with one line saying so; a path given that does not
// exist is an error.
TEST(InterfaceCli, EvalSaysOnceThatLpipsIsSkippedAndRefusesAMissingPath) {
  TempDir dir("interface_lpips");
  const Scene s = MakeScene(dir);
  const std::string eval = "cd " + dir.path() + " && " + WatergsBin() +
                           " eval --raw_path " + s.ply + " --input_path " +
                           s.ply + " --workspace_path " + s.ws + " --decoder " +
                           s.decoder +
                           " --message hex:a5c3 --attacks identity "
                           "--image_attacks ''";
  const auto skipped = RunCommand(eval);
  ASSERT_EQ(skipped.exit_code, 0) << skipped.output;
  const std::string line =
      "eval: LPIPS skipped: no weights at the default "
      "data/lpips/lpips_vgg.bin (relative to the current folder;";
  const size_t at = skipped.output.find(line);
  ASSERT_NE(at, std::string::npos) << skipped.output;
  EXPECT_EQ(skipped.output.find("LPIPS skipped", at + line.size()),
            std::string::npos)
      << skipped.output;
  const std::string missing = dir / "lpips.bin";
  ExpectOneLineError(RunCommand(eval + " --lpips_weights " + missing),
                     missing + ": LPIPS weights not found");
}

}  // namespace
}  // namespace watergs
