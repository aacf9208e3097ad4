// The malformed-input corpus beyond malformed_model_test.cc: COLMAP binaries
// truncated at every byte (so at every record and field boundary), text
// models truncated at every line, counts that disagree with the data or
// would need terabytes, negative and duplicate ids, binary images pointing to
// missing cameras; and, through the CLI, a non-ASCII workspace, an output
// folder that cannot be created, and a full disk. Every failure is one line
// naming the file, a non-zero exit, and no half-written output.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "gaussian/formats/ply_io.h"
#include "gaussian/point_init.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/training_views.h"
#include "synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::RunCommand;
using testing::WatergsBin;

class MalformedInput : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::SyntheticModelOptions options;
    options.model_ids = {1, 4};
    options.num_images = 3;
    options.num_points = 12;
    model_ = testing::MakeSyntheticReconstruction(options);
    WriteReconstruction(model_, dir_.path(), ModelFormat::kBinary);
    WriteReconstruction(model_, dir_ / "txt", ModelFormat::kText);
  }
  std::string Bytes(const std::string& file) const {
    const std::vector<uint8_t> bytes = ReadFileBytes(dir_ / file);
    return std::string(bytes.begin(), bytes.end());
  }
  // Plain write (no fsync: the cases are many and throwaway).
  void Put(const std::string& file, const std::string& bytes) const {
    std::ofstream(dir_ / file, std::ios::binary | std::ios::trunc) << bytes;
  }
  template <typename T>
  void Patch(const std::string& file, size_t offset, T value) const {
    std::string bytes = Bytes(file);
    ASSERT_LE(offset + sizeof(T), bytes.size());
    std::memcpy(bytes.data() + offset, &value, sizeof(T));
    Put(file, bytes);
  }
  void Replace(const std::string& file, const std::string& from,
               const std::string& to) const {
    std::string text = Bytes(file);
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    Put(file, text);
  }
  // Reading the model in `folder` ("" = the binary one) throws one line
  // naming `file` and containing `problem`.
  void ExpectError(const std::string& folder, const std::string& file,
                   const std::string& problem) const {
    try {
      ReadReconstruction(folder.empty() ? dir_.path() : dir_ / folder);
      ADD_FAILURE() << "accepted; expected " << file << ": " << problem;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(file + ": "), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }

  Reconstruction model_;
  testing::TempDir dir_{"malformed_input"};
};

TEST_F(MalformedInput, BinariesTruncatedAtEveryByte) {
  for (const char* file : {"cameras.bin", "images.bin", "points3D.bin"}) {
    const std::string bytes = Bytes(file);
    for (size_t keep = 0; keep < bytes.size(); ++keep) {
      Put(file, bytes.substr(0, keep));
      SCOPED_TRACE(std::string(file) + " cut at " + std::to_string(keep));
      ExpectError("", file, "truncated");
    }
    Put(file, bytes);
  }
  EXPECT_NO_THROW(ReadReconstruction(dir_.path()));
}

TEST_F(MalformedInput, TextTruncatedAtEveryLine) {
  // Each camera is used, each image observes points and each point is
  // observed, so dropping any record leaves a dangling reference, named in
  // the file that holds it: a cut cameras file leaves images of a missing
  // camera (images.txt), a cut points file leaves observed points missing
  // (points3D.txt). An images file cut between records leaves tracks that
  // point to a missing image (points3D.txt); one cut inside a record, after
  // its first line, leaves the image without its POINTS2D line (images.txt).
  for (const char* file :
       {"txt/cameras.txt", "txt/images.txt", "txt/points3D.txt"}) {
    const std::string text = Bytes(file);
    int cuts = 0, data_lines = 0;
    for (size_t at = text.find('\n'); at + 1 < text.size();
         at = text.find('\n', at + 1)) {
      const size_t line_start = at == 0 ? 0 : text.rfind('\n', at - 1) + 1;
      if (text[line_start] != '#') ++data_lines;
      if (text[at + 1] == '#') continue;  // still inside the comment header
      Put(file, text.substr(0, at + 1));
      SCOPED_TRACE(std::string(file) + " cut after byte " + std::to_string(at));
      const std::string name = file;
      if (name == "txt/cameras.txt") {
        ExpectError("txt", "txt/images.txt", "does not exist in cameras file");
      } else if (name == "txt/points3D.txt") {
        ExpectError("txt", "txt/points3D.txt", "observes (truncated file?)");
      } else if (data_lines % 2 == 1) {
        ExpectError("txt", "txt/images.txt",
                    "lacks its POINTS2D line (truncated file)");
      } else {
        ExpectError("txt", "txt/points3D.txt", "track refers to missing image");
      }
      ++cuts;
    }
    EXPECT_GE(cuts, 2) << file;
    Put(file, text);
  }
}

TEST_F(MalformedInput, PointsFileCutAtARecordNamesTheMissingPoint) {
  // A points3D file that ends early at a record boundary is still well
  // formed: the observations in the images file give it away.
  std::string text = Bytes("txt/points3D.txt");
  text.resize(text.rfind('\n', text.size() - 2) + 1);
  Put("txt/points3D.txt", text);
  ExpectError("txt", "points3D.txt", "observes (truncated file?)");
  std::string bytes = Bytes("points3D.bin");
  uint64_t count = 0;
  std::memcpy(&count, bytes.data(), 8);
  --count;
  std::memcpy(bytes.data(), &count, 8);
  // Drop the last record: walk the records to find where it starts.
  size_t at = 8;
  for (uint64_t k = 0; k < count; ++k) {
    uint64_t track = 0;
    std::memcpy(&track, bytes.data() + at + 43, 8);
    at += 43 + 8 + 8 * track;
  }
  Put("points3D.bin", bytes.substr(0, at));
  ExpectError("", "points3D.bin", "observes (truncated file?)");
}

TEST_F(MalformedInput, BinaryCountsDisagreeWithTheData) {
  // One record more than the file holds is a truncation; one less leaves
  // bytes the count does not explain.
  for (const char* file : {"cameras.bin", "images.bin", "points3D.bin"}) {
    const std::string bytes = Bytes(file);
    uint64_t count = 0;
    std::memcpy(&count, bytes.data(), 8);
    Patch<uint64_t>(file, 0, count + 1);
    ExpectError("", file, "truncated");
    Patch<uint64_t>(file, 0, count - 1);
    ExpectError("", file, "unexpected bytes");
    Put(file, bytes);
  }
}

TEST_F(MalformedInput, CountsThatWouldNeedTerabytes) {
  // Refused by size checks before any allocation: each message names the
  // claimed count.
  Patch<uint64_t>("cameras.bin", 0, uint64_t(1) << 41);
  ExpectError("", "cameras.bin", "2199023255552");
  WriteReconstruction(model_, dir_.path(), ModelFormat::kBinary);
  Patch<uint64_t>("images.bin", 0, uint64_t(1) << 42);
  ExpectError("", "images.bin", "4398046511104");
  WriteReconstruction(model_, dir_.path(), ModelFormat::kBinary);
  // First point3D: id(8) xyz(24) rgb(3) error(8), then its track length.
  Patch<uint64_t>("points3D.bin", 8 + 8 + 24 + 3 + 8, uint64_t(1) << 45);
  ExpectError("", "points3D.bin", "35184372088832");
}

TEST_F(MalformedInput, NegativeIdsInText) {
  Replace("txt/cameras.txt", "\n2 ", "\n-2 ");
  ExpectError("txt", "cameras.txt", "bad camera id `-2`");
  WriteReconstruction(model_, dir_ / "txt", ModelFormat::kText);
  const std::string points = Bytes("txt/points3D.txt");
  Put("txt/points3D.txt", points + "-7 0 0 0 1 2 3 0.5\n");
  ExpectError("txt", "points3D.txt", "`-7`");
  Put("txt/points3D.txt", points);
  // A negative image id inside a track.
  Put("txt/points3D.txt", points + "424242 0 0 0 1 2 3 0.5 -5 0\n");
  ExpectError("txt", "points3D.txt", "`-5`");
}

TEST_F(MalformedInput, DuplicateIdsInBinaries) {
  // cameras.bin: count(8), then camera 5: id(4) model(4) w(8) h(8) 8
  // params(64) (written in id order... the first id is read back and copied
  // into the second record).
  const std::string cameras = Bytes("cameras.bin");
  int32_t first_id = 0;
  std::memcpy(&first_id, cameras.data() + 8, 4);
  int32_t first_model = 0;
  std::memcpy(&first_model, cameras.data() + 12, 4);
  const size_t first_size = 4 + 4 + 8 + 8 + 8 * (first_model == 1 ? 4 : 8);
  Patch<int32_t>("cameras.bin", 8 + first_size, first_id);
  ExpectError("", "cameras.bin",
              "duplicate camera " + std::to_string(first_id));
  Put("cameras.bin", cameras);
  // points3D.bin: the second record gets the first one's id.
  const std::string points = Bytes("points3D.bin");
  uint64_t first_point = 0, track = 0;
  std::memcpy(&first_point, points.data() + 8, 8);
  std::memcpy(&track, points.data() + 8 + 43, 8);
  Patch<uint64_t>("points3D.bin", 8 + 43 + 8 + 8 * track, first_point);
  ExpectError("", "points3D.bin", "duplicate point3D");
}

TEST_F(MalformedInput, BinaryImagePointsToMissingCamera) {
  // images.bin: count(8), id(4) qvec(32) tvec(24), then camera_id.
  Patch<uint32_t>("images.bin", 8 + 4 + 32 + 24, 99);
  ExpectError("", "images.bin", "camera 99 does not exist");
}

// --- Through the CLI -------------------------------------------------------

// Exit code non-zero and one error line "error: ..." naming `what`, the
// last thing printed (progress lines before it are allowed).
void ExpectCliError(const testing::CommandResult& run,
                    const std::string& what) {
  EXPECT_NE(run.exit_code, 0) << run.output;
  const size_t at = run.output.find("error: ");
  ASSERT_NE(at, std::string::npos) << run.output;
  EXPECT_TRUE(at == 0 || run.output[at - 1] == '\n') << run.output;
  const std::string line = run.output.substr(at);
  EXPECT_NE(line.find(what), std::string::npos) << run.output;
  EXPECT_EQ(line.find('\n'), line.size() - 1) << run.output;
}

// A small workspace (COLMAP text model, PNGs rendered from Gaussians at its
// points) at `ws`, with image names given by `name_prefix`.
void MakeWorkspace(const std::string& ws, const std::string& name_prefix) {
  testing::SyntheticModelOptions options;
  options.num_images = 4;
  options.num_points = 80;
  options.width = 32;
  options.height = 24;
  Reconstruction model = testing::MakeSyntheticReconstruction(options);
  Reconstruction renamed;
  for (const auto& [id, camera] : model.Cameras()) renamed.AddCamera(camera);
  for (const auto& [id, image] : model.Images()) {
    Image copy = image;
    copy.name = name_prefix + image.name;
    renamed.AddImage(copy);
    renamed.RegisterImage(id);
  }
  for (const auto& [id, point] : model.Points3D()) {
    renamed.AddPoint3D(id, point);
  }
  WriteReconstruction(renamed, ws + "/sparse/0", ModelFormat::kText);
  CreateDirectories(ws + "/images");
  ImageRGB image(32, 24);
  for (size_t k = 0; k < image.data.size(); ++k) image.data[k] = (k % 7) / 7.f;
  for (const auto& [id, img] : renamed.Images()) {
    WritePng(ws + "/images/" + img.name, image);
  }
}

// `bytes` cut to half its length into `path` (plain write).
void WriteHalf(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size() / 2);
}

TEST(MalformedInputCli, TruncatedInputsOfEveryKind) {
  // A truncated model, PLY, checkpoint and decoder each stop their command
  // with one line naming the file, and the failed command writes nothing.
  testing::TempDir dir("truncated_cli");
  const std::string ws = dir / "ws";
  MakeWorkspace(ws, "");
  const std::string out = dir / "out";
  const std::string train = WatergsBin() + " train --workspace_path " + ws +
                            " --output_path " + out +
                            " --iterations 4 --checkpoint_every 2 "
                            "--sh_degree 0 --num_threads 1";
  ASSERT_EQ(RunCommand(train).exit_code, 0);
  const std::string model = dir / "model";
  ASSERT_EQ(
      RunCommand(WatergsBin() + " model_converter --sparse_path " + ws +
                 "/sparse/0 --output_path " + model + " --output_type BIN")
          .exit_code,
      0);
  WriteHalf(model + "/points3D.bin", ReadFileBytes(model + "/points3D.bin"));
  ExpectCliError(
      RunCommand(WatergsBin() + " model_info --sparse_path " + model),
      model + "/points3D.bin: ");
  const std::string ply = dir / "half.ply";
  WriteHalf(ply, ReadFileBytes(out + "/point_cloud.ply"));
  ExpectCliError(RunCommand(WatergsBin() + " ply_info --input_path " + ply),
                 ply + ": ");
  ExpectCliError(
      RunCommand(WatergsBin() + " attack --input_path " + ply +
                 " --attack identity --output_path " + dir / "attacked.ply"),
      ply + ": ");
  EXPECT_FALSE(fs::exists(dir / "attacked.ply"));
  // A truncated checkpoint: --resume refuses it and leaves every output as
  // it was.
  const std::string checkpoint = out + "/checkpoint.ckpt";
  WriteHalf(checkpoint, ReadFileBytes(checkpoint));
  const std::vector<uint8_t> cut = ReadFileBytes(checkpoint);
  const std::vector<uint8_t> cloud = ReadFileBytes(out + "/point_cloud.ply");
  ExpectCliError(RunCommand(train + " --resume"), checkpoint + ": ");
  EXPECT_EQ(ReadFileBytes(checkpoint), cut);
  EXPECT_EQ(ReadFileBytes(out + "/point_cloud.ply"), cloud);
  // A decoder file that is not one (here: half a PLY).
  ExpectCliError(
      RunCommand(WatergsBin() + " embed --input_path " + out +
                 "/point_cloud.ply --workspace_path " + ws + " --decoder " +
                 ply + " --message hex:a5 --output_path " + dir / "wm.ply"),
      ply + ": ");
  EXPECT_FALSE(fs::exists(dir / "wm.ply"));
}

TEST(MalformedInputCli, NonAsciiWorkspaceAndImageNames) {
  testing::TempDir dir("non_ascii");
  const std::string ws = dir / "données_日本/ws";
  MakeWorkspace(ws, "画像_");
  const std::string out = dir / "données_日本/出力";
  const auto run = RunCommand(WatergsBin() + " train --workspace_path '" + ws +
                              "' --output_path '" + out +
                              "' --iterations 3 --sh_degree 0 --num_threads 1");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_GT(ReadPly(out + "/point_cloud.ply").model.size(), 0u);
  // A missing file under a non-ASCII path is named byte for byte.
  ExpectCliError(RunCommand(WatergsBin() + " ply_info --input_path '" + out +
                            "/無い.ply'"),
                 out + "/無い.ply");
}

TEST(MalformedInputCli, OutputFolderThatCannotBeCreated) {
  testing::TempDir dir("bad_output");
  const std::string ws = dir / "ws";
  MakeWorkspace(ws, "");
  // The output's parent is a regular file: refused even as root.
  const std::string blocker = dir / "blocker";
  AtomicWriteFile(blocker, std::string("not a folder"));
  ExpectCliError(RunCommand(WatergsBin() + " train --workspace_path " + ws +
                            " --output_path " + blocker +
                            "/out --iterations 2 --num_threads 1"),
                 blocker + "/out");
  ExpectCliError(RunCommand(WatergsBin() + " model_converter --sparse_path " +
                            ws + "/sparse/0 --output_path " + blocker +
                            "/model --output_type BIN"),
                 blocker + "/model");
  EXPECT_EQ(ReadFileBytes(blocker).size(), 12u);
  if (::geteuid() != 0) {
    // A read-only folder (root would ignore the permission).
    const std::string locked = dir / "locked";
    CreateDirectories(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    ExpectCliError(
        RunCommand(WatergsBin() + " model_converter --sparse_path " + ws +
                   "/sparse/0 --output_path " + locked + " --output_type BIN"),
        locked);
    fs::permissions(locked, fs::perms::owner_all);
    EXPECT_TRUE(fs::is_empty(locked));
  }
}

TEST(MalformedInputCli, FullDiskKeepsThePreviousOutput) {
  // `ulimit -f` caps files at 64 KiB (SIGXFSZ ignored, so writes past it
  // fail with EFBIG as on a full disk); a 2000-Gaussian PLY needs ~200 KB.
  testing::TempDir dir("full_disk");
  GaussianModel model;
  model.sh_degree = 1;
  model.Resize(2000);
  for (float& q : model.quats) q = 0.5f;
  const std::string input = dir / "in.ply", output = dir / "out.ply";
  WritePly(input, model);
  AtomicWriteFile(output, std::string("previous output"));
  const auto run = RunCommand("trap '' XFSZ; ulimit -f 64; " + WatergsBin() +
                              " attack --input_path " + input +
                              " --attack identity --output_path " + output);
  ExpectCliError(run, output + ": write failed");
  const std::vector<uint8_t> kept = ReadFileBytes(output);
  EXPECT_EQ(std::string(kept.begin(), kept.end()), "previous output");
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos);
    ++entries;
  }
  EXPECT_EQ(entries, 2);
}

}  // namespace
}  // namespace watergs
