// CLI tests of what the commands refuse to overwrite and of when they check
// their outputs: model_converter into the folder of its input model, the
// three model files replaced as a set, train into a folder holding its
// inputs or an earlier run, and extract/attack outputs checked before the
// work (so that a mistyped path fails at once, not after it).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

// Names of the files in `folder`, sorted.
std::vector<std::string> FileNames(const std::string& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(ModelConverterCli, RefusesTheFolderOfItsInputModelHoweverSpelled) {
  TempDir dir("converter_in_place");
  const std::string ws = dir / "ws";
  const std::string model = ws + "/sparse/0";
  WriteReconstruction(testing::MakeSyntheticReconstruction({}), model,
                      ModelFormat::kBinary);
  const auto images = ReadFileBytes(model + "/images.bin");
  const auto points = ReadFileBytes(model + "/points3D.bin");
  fs::create_directory_symlink("sparse/0", ws + "/link");
  const std::string convert =
      WatergsBin() + " model_converter --output_type BIN --sparse_path ";
  for (const std::string& out :
       {model, model + "/.", ws + "/sparse/../sparse/0", ws + "/link"}) {
    const auto run = RunCommand(convert + ws + " --output_path " + out);
    ExpectOneLineError(run, out + ": holds the input model");
  }
  ExpectOneLineError(RunCommand(WatergsBin() +
                                " model_converter --output_type TXT "
                                "--sparse_path " +
                                model + " --output_path " + model),
                     "holds the input model");
  EXPECT_TRUE(ReadFileBytes(model + "/images.bin") == images) << "rewritten";
  EXPECT_TRUE(ReadFileBytes(model + "/points3D.bin") == points) << "rewritten";
  EXPECT_EQ(
      FileNames(model),
      (std::vector<std::string>{"cameras.bin", "images.bin", "points3D.bin"}));
  // Another folder is fine.
  const auto other = RunCommand(convert + ws + " --output_path " + (dir / "o"));
  EXPECT_EQ(other.exit_code, 0) << other.output;
}

// A failure on the last of the three files (here a folder in its place)
// replaces none of them: new cameras and images beside an old points3D
// would read as a model, a wrong one.
TEST(ModelConverterCli, WritesTheThreeFilesAsASet) {
  TempDir dir("converter_set");
  testing::SyntheticModelOptions options;
  WriteReconstruction(testing::MakeSyntheticReconstruction(options), dir / "in",
                      ModelFormat::kText);
  options.seed = 2;
  options.num_images = 4;
  const std::string out = dir / "out";
  WriteReconstruction(testing::MakeSyntheticReconstruction(options), out,
                      ModelFormat::kBinary);
  const auto cameras = ReadFileBytes(out + "/cameras.bin");
  const auto images = ReadFileBytes(out + "/images.bin");
  fs::remove(out + "/points3D.bin");
  fs::create_directory(out + "/points3D.bin");
  ExpectOneLineError(RunCommand(WatergsBin() +
                                " model_converter --output_type BIN "
                                "--sparse_path " +
                                (dir / "in") + " --output_path " + out),
                     out + "/points3D.bin: is a directory");
  EXPECT_TRUE(ReadFileBytes(out + "/cameras.bin") == cameras) << "replaced";
  EXPECT_TRUE(ReadFileBytes(out + "/images.bin") == images) << "replaced";
  EXPECT_EQ(FileNames(out), (std::vector<std::string>{
                                "cameras.bin", "images.bin", "points3D.bin"}));
}

TEST(TrainCli, RefusesFoldersHoldingInputsOrAnEarlierRun) {
  TempDir dir("train_output_safety");
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", testing::SmallSceneOptions());
  const std::vector<std::string> ws_files = FileNames(ws);
  const std::vector<std::string> image_files = FileNames(ws + "/images");
  const std::string train = WatergsBin() + " train --workspace_path " + ws +
                            " --iterations 3 --sh_degree 1 --num_threads 1";
  const std::pair<std::string, std::string> refused[] = {
      {ws, "is the workspace"},
      {ws + "/.", "is the workspace"},
      {ws + "/images", "is the image folder"},
      {ws + "/images/run", "lies inside the image folder"},
      {ws + "/sparse/0", "is the sparse model folder"}};
  for (const auto& [out, why] : refused) {
    ExpectOneLineError(RunCommand(train + " --output_path " + out), why);
  }
  EXPECT_EQ(FileNames(ws), ws_files);
  EXPECT_EQ(FileNames(ws + "/images"), image_files);

  // A run that fails on its inputs leaves no folder behind.
  const std::string never = dir / "never";
  ExpectOneLineError(RunCommand(WatergsBin() + " train --workspace_path " +
                                (dir / "missing") + " --output_path " + never),
                     "missing");
  EXPECT_FALSE(fs::exists(never));

  // A finished run is replaced only with --overwrite.
  const std::string out = dir / "run";
  const auto first = RunCommand(train + " --output_path " + out);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  const auto ply = ReadFileBytes(out + "/point_cloud.ply");
  ExpectOneLineError(RunCommand(train + " --seed 5 --output_path " + out),
                     out + ": holds an earlier run (point_cloud.ply)");
  EXPECT_TRUE(ReadFileBytes(out + "/point_cloud.ply") == ply) << "replaced";
  ExpectOneLineError(
      RunCommand(train + " --output_path " + out + " --resume --overwrite"),
      "not both");
  const auto replaced =
      RunCommand(train + " --seed 5 --overwrite --output_path " + out);
  ASSERT_EQ(replaced.exit_code, 0) << replaced.output;
  EXPECT_FALSE(ReadFileBytes(out + "/point_cloud.ply") == ply) << "kept";
}

// An interrupted run leaves its checkpoint and none of the final files: the
// case where replacing it loses the most work. A folder holding only the
// checkpoint is refused without --resume and left as it was, and --resume
// continues it. Each of the other run files alone is refused too.
TEST(TrainCli, RefusesAFolderHoldingOnlyTheCheckpointOfAnInterruptedRun) {
  TempDir dir("train_checkpoint_only");
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", testing::SmallSceneOptions());
  const std::string train = WatergsBin() + " train --workspace_path " + ws +
                            " --iterations 4 --sh_degree 1 --num_threads 1";
  const std::string out = dir / "run";
  const auto first =
      RunCommand(train + " --checkpoint_every 2 --output_path " + out);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  for (const std::string& name : FileNames(out)) {
    if (name != "checkpoint.ckpt") fs::remove(out + "/" + name);
  }
  ASSERT_EQ(FileNames(out), std::vector<std::string>{"checkpoint.ckpt"});
  const auto checkpoint = ReadFileBytes(out + "/checkpoint.ckpt");

  ExpectOneLineError(RunCommand(train + " --seed 5 --output_path " + out),
                     out + ": holds an earlier run (checkpoint.ckpt)");
  ExpectOneLineError(
      RunCommand(train + " --checkpoint_every 2 --output_path " + out),
      out + ": holds an earlier run (checkpoint.ckpt)");
  EXPECT_EQ(FileNames(out), std::vector<std::string>{"checkpoint.ckpt"});
  EXPECT_TRUE(ReadFileBytes(out + "/checkpoint.ckpt") == checkpoint)
      << "replaced";

  const auto resumed = RunCommand(train + " --resume --output_path " + out);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("train: resumed at iteration 4"),
            std::string::npos)
      << resumed.output;
  EXPECT_TRUE(fs::exists(out + "/point_cloud.ply"));

  for (const char* name : {"report.json", "cameras.json", "train_log.jsonl"}) {
    const std::string other = dir / (std::string("only_") + name);
    fs::create_directory(other);
    AtomicWriteFile(other + "/" + name, std::string());
    ExpectOneLineError(RunCommand(train + " --output_path " + other),
                       other + ": holds an earlier run (" + name + ")");
    EXPECT_EQ(FileNames(other), std::vector<std::string>{name});
  }
}

TEST(ExtractAndAttackCli, CheckTheirOutputsBeforeTheWork) {
  TempDir dir("outputs_first");
  GaussianModel truth;
  const std::string ws = testing::MakeRenderedWorkspace(
      dir / "ws", testing::SmallSceneOptions(), &truth);
  const std::string ply = dir / "model.ply";
  WritePly(ply, truth);
  const std::string decoder = testing::WriteTinyDecoder(dir / "decoder.bin");
  const std::string missing = dir / "missing";

  // One line: the error, and none of the work's lines before it.
  ExpectOneLineError(
      RunCommand(WatergsBin() + " extract --input_path " + ply +
                 " --workspace_path " + ws + " --decoder " + decoder +
                 " --message hex:a5c3 --json " + missing + "/r.json"),
      missing + "/r.json: output folder");
  ExpectOneLineError(
      RunCommand(WatergsBin() + " attack --input_path " + ply +
                 " --attack gn:0.01,similarity:10,0,0,0,1 --output_path " +
                 missing + "/a.ply"),
      missing + "/a.ply: output folder");
  fs::create_directory(dir / "a_folder.ply");
  ExpectOneLineError(
      RunCommand(WatergsBin() + " attack --input_path " + ply +
                 " --attack sh0 --output_path " + (dir / "a_folder.ply")),
      "is a directory");
  EXPECT_FALSE(fs::exists(missing));
}

}  // namespace
}  // namespace watergs
