// CLI tests of `watergs train`'s progress output and of what --iterations
// changes: held-out PSNR printed on a line of its own, and the position
// learning rate's decay over the run, which makes runs of different lengths
// differ from the start unless --position_lr_max_steps is fixed (as -h
// says).
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

// Each line of OUT/train_log.jsonl without its wall-clock "seconds".
std::vector<std::string> LogLines(const std::string& out) {
  std::ifstream in(out + "/train_log.jsonl");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    nlohmann::json j = nlohmann::json::parse(line);
    j.erase("seconds");
    lines.push_back(j.dump());
  }
  return lines;
}

TEST(TrainCli, PrintsHeldOutPsnrOnItsOwnLine) {
  TempDir dir("train_psnr_line");
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", testing::SmallSceneOptions());
  const auto run = RunCommand(
      WatergsBin() + " train --workspace_path " + ws + " --output_path " +
      (dir / "out") +
      " --iterations 4 --split train --test_iterations 2,4 --sh_degree 1 "
      "--num_threads 1");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  // One line per test iteration, starting the line, two decimals.
  std::istringstream lines(run.output);
  int found = 0;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("train: iteration ", 0) != 0) continue;
    EXPECT_NE(line.find(": held-out PSNR "), std::string::npos) << line;
    EXPECT_NE(line.find(" dB, SSIM "), std::string::npos) << line;
    EXPECT_NE(line.find("(1 view)"), std::string::npos) << line;
    const size_t at = line.find("PSNR ") + 5;
    const std::string number = line.substr(at, line.find(' ', at) - at);
    EXPECT_EQ(number.size() - number.find('.'), 3u) << line;
    ++found;
  }
  EXPECT_EQ(found, 2) << run.output;
  EXPECT_EQ(run.output.find("test PSNR"), std::string::npos) << run.output;
}

// -h says the position learning rate decays over --iterations unless
// --position_lr_max_steps is fixed; both halves of that hold.
TEST(TrainCli, IterationsChangeTheScheduleUnlessItsLengthIsFixed) {
  TempDir dir("train_prefix");
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", testing::SmallSceneOptions());
  const auto help = RunCommand(WatergsBin() + " train -h");
  // The help wraps at the widest option's column: read it as one line.
  std::string text;
  for (char c : help.output) {
    if (c == '\n' || c == ' ') {
      if (!text.empty() && text.back() != ' ') text += ' ';
    } else {
      text += c;
    }
  }
  EXPECT_NE(text.find("--position_lr_max_steps"), std::string::npos);
  EXPECT_NE(text.find("runs of different lengths differ"), std::string::npos)
      << help.output;
  const auto train = [&](const std::string& name, int iterations,
                         const std::string& extra) {
    const std::string out = dir / name;
    const auto run = RunCommand(
        WatergsBin() + " train --workspace_path " + ws + " --output_path " +
        out + " --iterations " + std::to_string(iterations) +
        " --log_every 1 --sh_degree 1 --num_threads 1 --seed 4" + extra);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return LogLines(out);
  };
  const std::vector<std::string> fixed_short =
      train("fixed_short", 10, " --position_lr_max_steps 40");
  const std::vector<std::string> fixed_long =
      train("fixed_long", 20, " --position_lr_max_steps 40");
  ASSERT_EQ(fixed_short.size(), 10u);
  ASSERT_EQ(fixed_long.size(), 20u);
  for (size_t k = 0; k < fixed_short.size(); ++k) {
    EXPECT_EQ(fixed_short[k], fixed_long[k]) << "iteration " << k + 1;
  }
  // By default the decay spans the run: the shorter run is not the start
  // of the longer one.
  const std::vector<std::string> own_short = train("own_short", 10, "");
  const std::vector<std::string> own_long = train("own_long", 20, "");
  ASSERT_EQ(own_short.size(), 10u);
  EXPECT_EQ(own_short[0], own_long[0]);  // before any step
  EXPECT_NE(own_short.back(), own_long[9]);
}

}  // namespace
}  // namespace watergs
