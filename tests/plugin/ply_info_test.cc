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

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"

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

// A little-endian file labelled big-endian reads as garbage: the total and
// the per-attribute NaN/Inf counts agree, and a warning says what is wrong.
TEST(PlyInfoCli, WrongByteOrderAgreesOnCountsAndWarns) {
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(200);
  for (size_t i = 0; i < model.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      model.means[3 * i + k] = 0.37f * float(i % 13) - 1.1f * k;
      model.log_scales[3 * i + k] = -4.3f + 0.013f * float(i);
      model.sh_dc[3 * i + k] = 0.21f * float(k) - 0.05f * float(i % 7);
    }
    for (int k = 0; k < 9; ++k) {
      model.sh_rest[9 * i + k] = 0.011f * float(int(i + k) % 11 - 5);
    }
    model.opacity_logits[i] = 0.7f + 0.003f * float(i);
    for (int k = 0; k < 4; ++k) {
      model.quats[4 * i + k] = 0.5f + 0.0017f * float(i) * float(k);
    }
  }
  const std::string good = TempPath("little.ply");
  WritePly(good, model);
  const RunResult plain = RunWatergs("ply_info --input_path " + good);
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  EXPECT_EQ(plain.output.find("warning"), std::string::npos) << plain.output;

  const auto bytes = ReadFileBytes(good);
  std::string text(bytes.begin(), bytes.end());
  const std::string little = "binary_little_endian";
  text.replace(text.find(little), little.size(), "binary_big_endian");
  const std::string swapped = TempPath("labelled_big.ply");
  AtomicWriteFile(swapped, text);
  const RunResult run = RunWatergs("ply_info --input_path " + swapped);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  // "NaN/Inf values:  N" and the last column of the ranges table.
  const size_t at = run.output.find("NaN/Inf values:  ");
  ASSERT_NE(at, std::string::npos) << run.output;
  const size_t total = std::stoul(run.output.substr(at + 17));
  size_t column = 0;
  int rows = 0;
  std::istringstream lines(run.output.substr(run.output.find("attribute")));
  std::string line;
  std::getline(lines, line);  // the heading
  while (std::getline(lines, line) && line.rfind("  ", 0) == 0) {
    column += std::stoul(line.substr(line.find_last_of(' ') + 1));
    ++rows;
  }
  EXPECT_EQ(rows, 12) << run.output;  // x y z, 3 scales, opacity, 3 colours,
                                      // f_rest, |rot|
  EXPECT_GT(total, 0u) << run.output;
  EXPECT_EQ(column, total) << run.output;
  EXPECT_NE(run.output.find("warning: "), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("byte order"), std::string::npos) << run.output;
}

TEST(PlyInfoCli, BadFileFailsWithOneLineNamingTheFile) {
  const std::string path = TempPath("not_a_ply.ply");
  AtomicWriteFile(path, std::string("solid cube\nfacet normal 0 0 1\n"));
  const RunResult run = RunWatergs("ply_info --input_path " + path);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_EQ(run.output,
            "error: " + path +
                ": a text file, not a 3DGS model (PLY, compressed PLY, .spz, "
                ".splat, SOG or its meta.json)\n");
  const RunResult missing = RunWatergs("ply_info");
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("input_path"), std::string::npos);
}

// ply_info and attack read every format by content (here a .spz and a
// .splat named .ply and .bin); attack runs a codec and writes the format
// its output's extension names.
TEST(PlyInfoCli, ReadsEveryFormatAndAttackWritesByExtension) {
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(40);
  for (size_t i = 0; i < model.size(); ++i) {
    model.means[3 * i] = 0.1f * float(i);
    model.quats[4 * i] = 1.f;
    model.log_scales[3 * i + 2] = -3.f;
    model.opacity_logits[i] = 1.f;
  }
  const std::string ply = TempPath("codec_in.ply");
  WritePly(ply, model);
  const std::string spz = TempPath("codec_out.spz");
  const RunResult attack = RunWatergs("attack --input_path " + ply +
                                      " --attack spz:2 --output_path " + spz);
  ASSERT_EQ(attack.exit_code, 0) << attack.output;
  EXPECT_NE(attack.output.find("spz:2: 40 Gaussians"), std::string::npos)
      << attack.output;
  // A .spz under a PLY's name is still read as SPZ.
  const std::string disguised = TempPath("disguised_spz.ply");
  std::filesystem::copy_file(spz, disguised,
                             std::filesystem::copy_options::overwrite_existing);
  const RunResult info = RunWatergs("ply_info --input_path " + disguised);
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("Format:          SPZ version 3"),
            std::string::npos)
      << info.output;
  EXPECT_NE(info.output.find("Gaussians:       40\n"), std::string::npos);
  EXPECT_NE(info.output.find("SH degree:       1"), std::string::npos);
  // From the .spz to a .splat (named .bin: read back by content) and to a
  // PLY in Inria's layout.
  const std::string splat = TempPath("codec_out.splat");
  ASSERT_EQ(RunWatergs("attack --input_path " + disguised +
                       " --attack identity --output_path " + splat)
                .exit_code,
            0);
  const std::string bin = TempPath("codec_out.bin");
  std::filesystem::copy_file(splat, bin,
                             std::filesystem::copy_options::overwrite_existing);
  const RunResult splat_info = RunWatergs("ply_info --input_path " + bin);
  EXPECT_NE(splat_info.output.find("Format:          antimatter15 .splat"),
            std::string::npos)
      << splat_info.output;
  EXPECT_NE(splat_info.output.find("SH degree:       0"), std::string::npos);
  const std::string back = TempPath("codec_back.ply");
  ASSERT_EQ(RunWatergs("attack --input_path " + bin +
                       " --attack compressed_ply --output_path " + back)
                .exit_code,
            0);
  const PlyData read = ReadPly(back);
  EXPECT_EQ(read.model.size(), 40u);
  EXPECT_EQ(read.layout.properties.size(), InriaPlyLayout(0).properties.size());
  // The SPZ through the SOG codec to a .sog, read back by content.
  const std::string sog = TempPath("codec_out.sog");
  const RunResult sog_attack = RunWatergs("attack --input_path " + spz +
                                          " --attack sog --output_path " + sog);
  ASSERT_EQ(sog_attack.exit_code, 0) << sog_attack.output;
  const RunResult sog_info = RunWatergs("ply_info --input_path " + sog);
  EXPECT_NE(sog_info.output.find("Format:          PlayCanvas SOG (bundled, "
                                 "SH palette of 32, written by watergs)"),
            std::string::npos)
      << sog_info.output;
  EXPECT_NE(sog_info.output.find("Gaussians:       40\n"), std::string::npos);
}

}  // namespace
}  // namespace watergs
