// CLI tests of the interface the commands share: one --sparse_path option
// everywhere (train's old --input_path kept as an alias), images optional
// where no ground truth is needed, `watergs help <command>`, --version,
// defaults printed as written, the message formats and their limit, and
// errors that name the right option or file in readable text.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/extractor.h"

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

TEST(InterfaceCli, HelpVersionDefaultsAndMessageFormats) {
  const auto help = RunCommand(WatergsBin() + " help embed");
  ASSERT_EQ(help.exit_code, 0) << help.output;
  EXPECT_EQ(help.output.rfind("Usage: watergs embed", 0), 0u) << help.output;
  EXPECT_NE(help.output.find("text:TEXT"), std::string::npos) << help.output;
  // As written, not as the nearest double prints with 17 digits.
  EXPECT_NE(help.output.find("--gamma arg (=0.03)"), std::string::npos)
      << help.output;
  EXPECT_EQ(help.output.find("0.0299"), std::string::npos) << help.output;
  ExpectOneLineError(RunCommand(WatergsBin() + " help nosuch"), "nosuch");

  const auto version = RunCommand(WatergsBin() + " --version");
  ASSERT_EQ(version.exit_code, 0) << version.output;
  EXPECT_EQ(version.output.rfind("watergs ", 0), 0u) << version.output;
  EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(version.output[8])))
      << version.output;
}

// `watergs --version` names the commit the binary was built from (and
// whether the tree had uncommitted changes), and every JSON a command writes
// carries the command as run, the version and the commit.
TEST(InterfaceCli, VersionNamesTheCommitAndJsonNamesTheCommand) {
  const auto version = RunCommand(WatergsBin() + " --version");
  ASSERT_EQ(version.exit_code, 0) << version.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      version.output, m,
      std::regex("^watergs ([0-9][^\\n]*)\\ncommit ([0-9a-f]{40}|unknown)"
                 "( \\(uncommitted changes\\))?\\n$")))
      << version.output;
  const std::string number = m[1], commit = m[2];
  // Built from this git checkout (the tests' sources), the commit is known.
  if (RunCommand("git -C " + std::string(WATERGS_SOURCE_DIR) +
                 " rev-parse HEAD")
          .exit_code == 0) {
    EXPECT_NE(commit, "unknown") << version.output;
  }

  TempDir dir("interface_provenance");
  const Scene s = MakeScene(dir);
  const std::string json = dir / "extract.json";
  const std::string args = "extract --input_path " + s.ply +
                           " --workspace_path " + s.ws + " --decoder " +
                           s.decoder + " --message hex:a5c3 --json " + json;
  const auto run = RunCommand(WatergsBin() + " " + args);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json provenance = ReadJson(json)["provenance"];
  EXPECT_EQ(provenance["command"], "watergs " + args) << provenance;
  EXPECT_EQ(provenance["version"], number) << provenance;
  EXPECT_EQ(provenance["commit"], commit) << provenance;
  EXPECT_EQ(provenance["dirty"].is_null(), commit == "unknown") << provenance;
  if (!provenance["dirty"].is_null()) {
    EXPECT_EQ(provenance["dirty"].get<bool>(), m[3].matched) << provenance;
  }
}

TEST(InterfaceCli, MessageTooLongStatesTheLimitInCharacters) {
  TempDir dir("interface_message");
  const Scene s = MakeScene(dir);
  const std::string extract = WatergsBin() + " extract --input_path " + s.ply +
                              " --workspace_path " + s.ws + " --decoder " +
                              s.decoder + " --message ";
  // The tiny decoder reads 16 bits.
  ExpectOneLineError(RunCommand(extract + "text:abc"),
                     "needs 24 bits but the decoder reads 16: at most 2 "
                     "characters of ASCII text");
  ExpectOneLineError(RunCommand(extract + "abc"), "at most 2 characters");
  ExpectOneLineError(RunCommand(extract + "hex:a5c3f"), "at most 4 hex digits");
  ExpectOneLineError(RunCommand(extract + "bits:00110011001100110"),
                     "at most 16 bits");
}

// The model lives outside sparse/0: every command finds it with
// --sparse_path (train also with its old name, on the command line and in a
// project file).
TEST(InterfaceCli, SparsePathOnEveryCommandThatReadsAWorkspace) {
  TempDir dir("interface_sparse");
  const Scene s = MakeScene(dir);
  const std::string model = dir / "model";
  fs::rename(s.ws + "/sparse/0", model);
  for (const char* command :
       {"train", "render", "embed", "extract", "eval", "concat_embed"}) {
    const auto help = RunCommand(WatergsBin() + " " + command + " -h");
    EXPECT_NE(help.output.find("--sparse_path"), std::string::npos) << command;
  }
  const std::string train = WatergsBin() + " train --workspace_path " + s.ws +
                            " --iterations 2 --sh_degree 1 --num_threads 1";
  const auto by_name = RunCommand(train + " --sparse_path " + model +
                                  " --output_path " + (dir / "t1"));
  EXPECT_EQ(by_name.exit_code, 0) << by_name.output;
  const auto by_alias = RunCommand(train + " --input_path=" + model +
                                   " --output_path " + (dir / "t2"));
  EXPECT_EQ(by_alias.exit_code, 0) << by_alias.output;
  const std::string ini = dir / "train.ini";
  AtomicWriteFile(ini, "input_path = " + model + "\n");
  const auto from_ini = RunCommand(train + " --project_path " + ini +
                                   " --output_path " + (dir / "t3"));
  EXPECT_EQ(from_ini.exit_code, 0) << from_ini.output;
  EXPECT_NE(RunCommand(WatergsBin() + " train -h")
                .output.find("--input_path = --sparse_path"),
            std::string::npos);
  ExpectOneLineError(
      RunCommand(train + " --sparse_path " + model + " --input_path " + model +
                 " --output_path " + (dir / "t4")),
      "--sparse_path");

  const auto render = RunCommand(
      WatergsBin() + " render --input_path " + s.ply + " --workspace_path " +
      s.ws + " --sparse_path " + model + " --output_path " + (dir / "r"));
  EXPECT_EQ(render.exit_code, 0) << render.output;
  const std::string with_model =
      " --input_path " + s.ply + " --workspace_path " + s.ws + " --decoder " +
      s.decoder + " --message hex:a5c3 " + "--sparse_path " + model;
  const auto extract = RunCommand(WatergsBin() + " extract" + with_model);
  EXPECT_EQ(extract.exit_code, 0) << extract.output;
  const auto embed = RunCommand(
      WatergsBin() + " embed" + with_model +
      " --iterations 1 --check_every 1 --check_views 1 --crop_size 16 "
      "--densify off --num_threads 1 --output_path " +
      (dir / "wm.ply"));
  EXPECT_EQ(embed.exit_code, 0) << embed.output;
  const auto eval =
      RunCommand(WatergsBin() + " eval --raw_path " + s.ply + with_model +
                 " --attacks identity --image_attacks '' --lpips_weights ''");
  EXPECT_EQ(eval.exit_code, 0) << eval.output;
  const auto concat = RunCommand(
      WatergsBin() + " concat_embed" + with_model +
      " --iterations 1 --check_views 1 --crop_size 16 --num_threads 1 "
      "--output_path " +
      (dir / "concat.ply"));
  EXPECT_EQ(concat.exit_code, 0) << concat.output;
}

// Without an image folder, commands that only render cameras (extract,
// render) or can compare renders with each other (eval) still run; those
// that fit images (train, embed) say the folder is missing.
TEST(InterfaceCli, ImagesOptionalWhereNoGroundTruthIsNeeded) {
  TempDir dir("interface_no_images");
  const Scene s = MakeScene(dir);
  fs::remove_all(s.ws + "/images");
  const std::string common = " --input_path " + s.ply + " --workspace_path " +
                             s.ws + " --decoder " + s.decoder +
                             " --message hex:a5c3";
  const auto extract = RunCommand(WatergsBin() + " extract" + common +
                                  " --json " + (dir / "x.json"));
  ASSERT_EQ(extract.exit_code, 0) << extract.output;
  EXPECT_EQ(ReadJson(dir / "x.json")["num_views"], 6);

  const auto eval = RunCommand(
      WatergsBin() + " eval --raw_path " + s.ply + common +
      " --attacks identity --image_attacks '' --lpips_weights '' --views all "
      "--output_path " +
      (dir / "report"));
  ASSERT_EQ(eval.exit_code, 0) << eval.output;
  EXPECT_NE(eval.output.find("no ground truth"), std::string::npos)
      << eval.output;
  const auto report = ReadJson(dir / "report.json");
  EXPECT_TRUE(report["quality"][0]["mean"]["psnr"].is_null());
  EXPECT_EQ(report["quality"][1]["comparison"], "watermarked vs raw renders");
  EXPECT_DOUBLE_EQ(report["quality"][1]["mean"]["ms_ssim"].get<double>(), 1.0);
  EXPECT_EQ(report["robustness"].size(), 2u);

  const auto render = RunCommand(
      WatergsBin() + " render --input_path " + s.ply + " --workspace_path " +
      s.ws + " --split all --output_path " + (dir / "renders"));
  ASSERT_EQ(render.exit_code, 0) << render.output;
  EXPECT_NE(render.output.find("no PSNR"), std::string::npos) << render.output;
  EXPECT_TRUE(fs::exists(dir / "renders/frame_1000.png")) << render.output;
  // The rendered cameras beside them, with the principal point Inria's
  // cameras.json leaves out (the web viewer harness, tests/viewer, reads it).
  const auto rendered = ReadJson(dir / "renders/cameras.json");
  ASSERT_FALSE(rendered.empty());
  EXPECT_EQ(rendered[0]["img_name"], "frame_1000");
  for (const char* key : {"cx", "cy"}) {
    ASSERT_TRUE(rendered[0].contains(key)) << key;
    EXPECT_GT(rendered[0][key].get<double>(), 0.0) << key;
  }
  EXPECT_LT(rendered[0]["cx"].get<double>(),
            rendered[0]["width"].get<double>());
  // Free viewpoints: their cameras beside the images (Inria's cameras.json),
  // the ones extract --num_views samples for that seed.
  const auto free = RunCommand(
      WatergsBin() + " render --input_path " + s.ply + " --workspace_path " +
      s.ws + " --num_views 3 --seed 4 --output_path " + (dir / "free"));
  ASSERT_EQ(free.exit_code, 0) << free.output;
  const auto cameras = ReadJson(dir / "free/cameras.json");
  WorkspaceOptions workspace_options;
  workspace_options.workspace_path = s.ws;
  workspace_options.images_optional = true;
  const Workspace workspace = Workspace::Open(workspace_options);
  const std::vector<RenderCamera> expected =
      SampleFreeViewpoints(WorkspaceViews(workspace), 3, 4);
  ASSERT_EQ(cameras.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(cameras[k]["img_name"], "free_00" + std::to_string(k));
    EXPECT_NEAR(cameras[k]["fx"].get<double>(), expected[k].fx, 1e-9);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(cameras[k]["position"][a].get<double>(),
                  expected[k].Center()[a], 1e-9);
    }
  }

  ExpectOneLineError(RunCommand(WatergsBin() + " train --workspace_path " +
                                s.ws + " --output_path " + (dir / "t")),
                     "image folder not found");
  ExpectOneLineError(RunCommand(WatergsBin() + " embed" + common +
                                " --output_path " + (dir / "wm.ply")),
                     "image folder not found");
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

// Errors name the option or file at fault, in printable text, and counts
// read as English.
TEST(InterfaceCli, ErrorsNameTheRightThingReadably) {
  TempDir dir("interface_errors");
  const Scene s = MakeScene(dir);
  const std::string extract = WatergsBin() + " extract --input_path " + s.ply +
                              " --workspace_path " + s.ws + " --decoder " +
                              s.decoder + " --scene_transform ";
  const std::string missing = dir / "moved.ply.transform.txt";
  const auto no_file = RunCommand(extract + missing);
  ExpectOneLineError(no_file, missing + ": --scene_transform file not found");
  EXPECT_EQ(no_file.output.find("--attack"), std::string::npos)
      << no_file.output;
  const auto bad_number = RunCommand(extract + "similarity:1,x,0,0,1");
  ExpectOneLineError(bad_number, "--scene_transform: similarity: 'x'");
  EXPECT_EQ(bad_number.output.find("--attack"), std::string::npos);
  AtomicWriteFile(dir / "bad.transform.txt", std::string("similarity:1,2\n"));
  ExpectOneLineError(RunCommand(extract + (dir / "bad.transform.txt")),
                     dir / "bad.transform.txt: similarity:1,2");

  // A binary PLY whose header lacks end_header: the bytes are escaped.
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\n"
      "property float x\n";
  for (int b = 0; b < 256; ++b) {
    if (b != '\n') bytes += static_cast<char>(b);
  }
  bytes += "\n";
  const std::string ply = dir / "no_end_header.ply";
  AtomicWriteFile(ply, bytes);
  const auto header =
      RunCommand(WatergsBin() + " ply_info --input_path " + ply);
  ExpectOneLineError(header, ply + ": binary bytes in the PLY header");
  EXPECT_NE(header.output.find("no end_header"), std::string::npos);
  EXPECT_NE(header.output.find("\\x1b"), std::string::npos) << header.output;
  for (size_t k = 0; k + 1 < header.output.size(); ++k) {
    const auto c = static_cast<unsigned char>(header.output[k]);
    EXPECT_TRUE(c >= 0x20 && c < 0x7f) << "byte " << int(c) << " at " << k;
  }

  // Counts: "all 6 views", "1 test view", "1 held-out view".
  const std::string render = WatergsBin() + " render --input_path " + s.ply +
                             " --workspace_path " + s.ws + " --output_path " +
                             (dir / "r") + " --split ";
  const auto all = RunCommand(render + "all");
  EXPECT_NE(all.output.find("render: all 6 views, mean PSNR"),
            std::string::npos)
      << all.output;
  const auto test = RunCommand(render + "test");
  EXPECT_NE(test.output.find("render: 1 test view, mean PSNR"),
            std::string::npos)
      << test.output;
  const auto eval = RunCommand(
      WatergsBin() + " eval --raw_path " + s.ply + " --input_path " + s.ply +
      " --workspace_path " + s.ws + " --decoder " + s.decoder +
      " --message hex:a5c3 --attacks identity --image_attacks '' "
      "--lpips_weights ''");
  ASSERT_EQ(eval.exit_code, 0) << eval.output;
  EXPECT_NE(eval.output.find("Gaussians), 1 held-out view of"),
            std::string::npos)
      << eval.output;
  EXPECT_NE(eval.output.find("(mean over 1 view)"), std::string::npos);
}

}  // namespace
}  // namespace watergs
