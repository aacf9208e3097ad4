// CLI test of `watergs ply_info` (binary from env WATERGS_BIN).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>

#include "gaussian/file_util.h"
#include "gaussian/ply_io.h"

namespace watergs {
namespace {

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

RunResult RunWatergs(const std::string& args) {
  const char* bin = std::getenv("WATERGS_BIN");
  EXPECT_NE(bin, nullptr) << "WATERGS_BIN is not set";
  RunResult result;
  if (bin == nullptr) return result;
  FILE* pipe = ::popen((std::string(bin) + " " + args + " 2>&1").c_str(), "r");
  std::array<char, 4096> buf;
  size_t got;
  while ((got = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) {
    result.output.append(buf.data(), got);
  }
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string TempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_ply_info_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

// The three numbers (min, max, mean) of a row of the ranges table.
std::array<double, 3> RangeRow(const std::string& output,
                               const std::string& label) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("  " + label + " ", 0) != 0) continue;
    std::istringstream values(line.substr(2 + label.size()));
    std::array<double, 3> row{};
    values >> row[0] >> row[1] >> row[2];
    return row;
  }
  ADD_FAILURE() << "no row " << label << " in:\n" << output;
  return {};
}

TEST(PlyInfoCli, ReportsCountDegreeRangesAndNonFinite) {
  GaussianModel model;
  model.sh_degree = 2;
  model.Resize(4);
  const float opacity_logits[] = {0.f, std::log(3.f), 0.f, 0.f};  // 0.5, 0.75
  for (int i = 0; i < 4; ++i) {
    model.opacity_logits[i] = opacity_logits[i];
    model.means[3 * i] = float(i);  // x = 0, 1, 2, 3
    model.log_scales[3 * i + 1] = std::log(0.01f * (i + 1));
  }
  model.means[3 * 2 + 2] = std::numeric_limits<float>::quiet_NaN();
  model.sh_rest[5] = std::numeric_limits<float>::infinity();
  const std::string path = TempPath("model.ply");
  WritePly(path, model);

  const RunResult run = RunWatergs("ply_info --input_path " + path);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("Gaussians:       4\n"), std::string::npos);
  EXPECT_NE(run.output.find("SH degree:       2 (24 f_rest)"),
            std::string::npos);
  EXPECT_NE(run.output.find("NaN/Inf values:  2\n"), std::string::npos);
  EXPECT_NE(run.output.find("x y z nx ny nz f_dc_0..2 f_rest_0..23 opacity "
                            "scale_0..2 rot_0..3"),
            std::string::npos)
      << run.output;
  const double bytes_per_gaussian = (6 + 3 + 24 + 1 + 3 + 4) * 4;
  EXPECT_NE(run.output.find("(vertex data " +
                            std::to_string(int(bytes_per_gaussian)) + ".00)"),
            std::string::npos)
      << run.output;
  const auto x = RangeRow(run.output, "x");
  EXPECT_DOUBLE_EQ(x[0], 0.0);
  EXPECT_DOUBLE_EQ(x[1], 3.0);
  EXPECT_DOUBLE_EQ(x[2], 1.5);
  const auto opacity = RangeRow(run.output, "opacity (sigmoid)");
  EXPECT_NEAR(opacity[0], 0.5, 1e-5);
  EXPECT_NEAR(opacity[1], 0.75, 1e-5);
  EXPECT_NEAR(opacity[2], (0.5 * 3 + 0.75) / 4, 1e-5);
  const auto scale = RangeRow(run.output, "scale_1 (exp)");
  EXPECT_NEAR(scale[0], 0.01, 1e-6);
  EXPECT_NEAR(scale[1], 0.04, 1e-6);
}

TEST(PlyInfoCli, BadFileFailsWithOneLineNamingTheFile) {
  const std::string path = TempPath("not_a_ply.ply");
  AtomicWriteFile(path, std::string("solid cube\nfacet normal 0 0 1\n"));
  const RunResult run = RunWatergs("ply_info --input_path " + path);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_EQ(run.output, "error: " + path +
                            ": not a PLY file (does not start with 'ply')\n");
  const RunResult missing = RunWatergs("ply_info");
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("input_path"), std::string::npos);
}

}  // namespace
}  // namespace watergs
