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
  const auto run =
      RunCommand(WatergsBin() + " train --workspace_path " + ws +
                 " --output_path " + (dir / "out") +
                 " --iterations 4 --eval --test_iterations 2,4 --sh_degree 1 "
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

}  // namespace
}  // namespace watergs
