// CLI tests of the interface the commands share: one --sparse_path option
// everywhere (train's old --input_path kept as a deprecated alias), one name
// per concept on every command (docs/cli.md, "Option names"), old names
// working with one notice line, images optional
// where no ground truth is needed, `watergs help <command>`, --version,
// defaults printed as written, the message formats and their limit, and
// errors that name the right option or file in readable text.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
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
  EXPECT_NE(by_alias.output.find("notice: --input_path is deprecated for "
                                 "train; use --sparse_path\n"),
            std::string::npos)
      << by_alias.output;
  const std::string ini = dir / "train.ini";
  AtomicWriteFile(ini, "input_path = " + model + "\n");
  const auto from_ini = RunCommand(train + " --project_path " + ini +
                                   " --output_path " + (dir / "t3"));
  EXPECT_EQ(from_ini.exit_code, 0) << from_ini.output;
  EXPECT_NE(RunCommand(WatergsBin() + " train -h")
                .output.find("--input_path = --sparse_path (deprecated)"),
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

// The stderr lines of `command` (its stdout dropped).
std::vector<std::string> StderrLines(const std::string& command) {
  const auto run = RunCommand("{ " + command + " 2>&1 >/dev/null; }");
  std::vector<std::string> lines;
  std::istringstream in(run.output);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// An old option name still works and says so in exactly one line naming the
// new name (once, whether typed or in the project file); the new name, the
// same command, prints nothing on stderr.
TEST(InterfaceCli, OldOptionNamesWorkWithOneNoticeNamingTheNewName) {
  TempDir dir("interface_old_names");
  const std::string model = dir / "sparse";
  WriteReconstruction(testing::MakeSyntheticReconstruction({}), model,
                      ModelFormat::kBinary);
  const std::string info = WatergsBin() + " model_info";
  const auto by_new = RunCommand(info + " --sparse_path " + model);
  ASSERT_EQ(by_new.exit_code, 0) << by_new.output;
  EXPECT_TRUE(StderrLines(info + " --sparse_path " + model).empty());
  const auto by_old = RunCommand(info + " --input_path " + model);
  ASSERT_EQ(by_old.exit_code, 0) << by_old.output;
  const std::vector<std::string> notice =
      StderrLines(info + " --input_path " + model);
  ASSERT_EQ(notice.size(), 1u) << by_old.output;
  EXPECT_EQ(notice[0],
            "notice: --input_path is deprecated for model_info; use "
            "--sparse_path");
  // The same figures either way, the notice aside.
  EXPECT_EQ(by_old.output, notice[0] + "\n" + by_new.output);
  const std::string ini = dir / "info.ini";
  AtomicWriteFile(ini, "input_path = " + model + "\n");
  EXPECT_EQ(StderrLines(info + " --project_path " + ini),
            std::vector<std::string>{notice[0]});

  const std::string convert = WatergsBin() +
                              " model_converter --output_type TXT "
                              "--output_path ";
  EXPECT_TRUE(StderrLines(convert + (dir / "txt1") + " --sparse_path " + model)
                  .empty());
  EXPECT_EQ(StderrLines(convert + (dir / "txt2") + " --input_path " + model),
            std::vector<std::string>{
                "notice: --input_path is deprecated for model_converter; "
                "use --sparse_path"});
  EXPECT_EQ(ReadFileBytes(dir / "txt1/images.txt"),
            ReadFileBytes(dir / "txt2/images.txt"));

  // A boolean old name standing for a value (train --eval is --split
  // train): one notice naming both, and the same refusal as the new name.
  const std::string train = WatergsBin() + " train --workspace_path " +
                            (dir / "missing") + " --output_path " + (dir / "t");
  const std::vector<std::string> eval = StderrLines(train + " --eval");
  ASSERT_EQ(eval.size(), 2u);
  EXPECT_EQ(eval[0],
            "notice: --eval is deprecated for train; use --split train");
  EXPECT_EQ(eval[1], StderrLines(train + " --split train").at(0));
  EXPECT_EQ(StderrLines(train + " --split train").size(), 1u);
  ExpectOneLineError(RunCommand(train + " --eval --split all"), "split");
}

// One option's name, whether it takes a value or is a boolean, and its help
// text, from a command's -h (options only, not the aliases).
struct HelpOption {
  std::string name, syntax, help;
};

std::vector<HelpOption> HelpOptions(const std::string& help) {
  std::vector<HelpOption> options;
  std::istringstream in(help);
  const std::regex line_re(
      R"(^  (?:-h \[ )?--([a-z0-9_]+)( \]|\s*\[=[^\]]*\]|\s+arg)?)"
      R"(\s*(?:\(=[^)]*\))?\s*(.*)$)");
  bool started = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("Options:", 0) == 0) started = true;
    if (line.rfind("Aliases:", 0) == 0) break;
    if (!started) continue;
    std::smatch m;
    if (std::regex_match(line, m, line_re)) {
      options.push_back({m[1], m[2], m[3]});
    } else if (!options.empty()) {
      options.back().help += " " + line;
    }
  }
  // Help text as one line, single-spaced.
  for (HelpOption& o : options) {
    o.help = std::regex_replace(o.help, std::regex(" +"), " ");
    o.help = std::regex_replace(o.help, std::regex("^ | $"), "");
  }
  return options;
}

// The names a command's -h breaks the rules of docs/cli.md ("Option names")
// with, one line each.
std::vector<std::string> NamingViolations(const std::string& command,
                                          const std::string& help) {
  std::vector<std::string> bad;
  const auto say = [&](const std::string& what) {
    bad.push_back(command + ": " + what);
  };
  for (const HelpOption& o : HelpOptions(help)) {
    const std::string& n = o.name;
    // --input_path is a 3DGS model file; a sparse model is --sparse_path.
    if (n == "input_path" && o.help.find("PLY") == std::string::npos) {
      say("--input_path is not a model file (PLY ...): " + o.help);
    }
    if (o.help.rfind("Sparse model", 0) == 0 && n != "sparse_path") {
      say("a sparse model as --" + n + " (use --sparse_path)");
    }
    // Views: --split, and only --split.
    for (const char* views :
         {"views", "eval", "which_views", "test_views", "train_views",
          "held_out", "holdout", "test_split", "view_split"}) {
      if (n == views) say("views chosen by --" + n + " (use --split)");
    }
    if (n == "split" && o.help.find("train") == std::string::npos) {
      say("--split does not name its values: " + o.help);
    }
    // JSON output: --json.
    if (n != "json" && (n.find("json") != std::string::npos ||
                        (std::regex_search(o.help, std::regex("^[Ww]rite")) &&
                         o.help.find("JSON") != std::string::npos))) {
      say("JSON written by --" + n + " (use --json)");
    }
    // Booleans: one style, `--name [0|1]`.
    if (n != "help" && o.syntax.empty()) {
      say("--" + n + " is a bare switch (use AddFlag: --" + n + " [0|1])");
    }
    if (o.syntax.find("[=") != std::string::npos &&
        o.syntax.find("[=0|1(=1)]") == std::string::npos) {
      say("--" + n + " is a boolean of another style: " + o.syntax);
    }
    // The reading: --reading owner|blind.
    if (n != "reading" && (n.find("reading") != std::string::npos ||
                           n == "owner" || n == "blind")) {
      say("the reading chosen by --" + n + " (use --reading)");
    }
    if (n == "reading" && (o.help.find("owner") == std::string::npos ||
                           o.help.find("blind") == std::string::npos)) {
      say("--reading does not name owner and blind: " + o.help);
    }
  }
  return bad;
}

// The rules hold on every registered command: --input_path is a model file
// everywhere, views are chosen by --split, JSON is written by --json, every
// boolean takes `--name [0|1]`, the reading is --reading. (A command that
// registers, say, eval's old `--views` again fails here.)
TEST(InterfaceCli, OptionNamesFollowOneRulePerConcept) {
  // The checker itself catches each kind of name.
  EXPECT_EQ(NamingViolations("x",
                             "Options:\n"
                             "  --input_path arg      Sparse model folder\n"
                             "  --views arg (=test)   test or all\n"
                             "  --report_json arg     JSON here\n"
                             "  --overwrite           Replace it\n"
                             "  --owner_reading arg   owner\n")
                .size(),
            6u);
  EXPECT_TRUE(NamingViolations("x",
                               "Options:\n"
                               "  -h [ --help ]         Print this help\n"
                               "  --input_path arg      The model (PLY)\n"
                               "  --split arg (=all)    all, train or test\n"
                               "  --json arg            Write JSON here\n"
                               "  --resume [=0|1(=1)] (=0)\n"
                               "                        Continue\n"
                               "  --reading arg         owner or blind\n"
                               "\nAliases:\n  --eval = --split train\n")
                  .empty());

  const auto list = RunCommand(WatergsBin() + " help");
  ASSERT_EQ(list.exit_code, 0) << list.output;
  std::istringstream lines(list.output.substr(list.output.find("Commands:")));
  std::string line;
  std::getline(lines, line);
  int commands = 0;
  std::vector<std::string> bad;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::string name;
    if (!(words >> name)) continue;
    ++commands;
    const auto help = RunCommand(WatergsBin() + " " + name + " -h");
    ASSERT_EQ(help.exit_code, 0) << name << ": " << help.output;
    EXPECT_GE(HelpOptions(help.output).size(), 4u) << name << help.output;
    for (const std::string& b : NamingViolations(name, help.output)) {
      bad.push_back(b);
    }
  }
  EXPECT_GE(commands, 20);
  std::string all;
  for (const std::string& b : bad) all += b + "\n";
  EXPECT_TRUE(bad.empty()) << all;
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
      " --attacks identity --image_attacks '' --lpips_weights '' --split all "
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
