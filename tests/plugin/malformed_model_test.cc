// Bad COLMAP models: every case must raise one watergs::Error whose single
// line names the offending file and the problem, and the CLI must exit
// non-zero with that line. One test per kind of bad input.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

class MalformedModel : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::SyntheticModelOptions options;
    options.model_ids = {1, 4};
    options.num_images = 4;
    options.num_points = 40;
    WriteReconstruction(testing::MakeSyntheticReconstruction(options),
                        dir_.path(), ModelFormat::kBinary);
    WriteReconstruction(testing::MakeSyntheticReconstruction(options),
                        dir_ / "txt", ModelFormat::kText);
  }
  std::string Bytes(const std::string& file) const {
    const std::vector<uint8_t> bytes = ReadFileBytes(dir_ / file);
    return std::string(bytes.begin(), bytes.end());
  }
  void Put(const std::string& file, const std::string& bytes) const {
    AtomicWriteFile(dir_ / file, bytes);
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
  // Reading `model` (relative folder) fails with one line naming `file`
  // and containing `problem`; with `check_cli`, `watergs model_info` too
  // exits 1 printing that line (a few cases only: each run costs a process).
  void ExpectError(const std::string& model, const std::string& file,
                   const std::string& problem, bool check_cli = false) const {
    const std::string path = model.empty() ? dir_.path() : dir_ / model;
    try {
      ReadReconstruction(path);
      ADD_FAILURE() << "no error for " << problem;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(file), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
    if (!check_cli) return;
    const testing::CommandResult cli = testing::RunCommand(
        testing::WatergsBin() + " model_info --sparse_path " + path);
    EXPECT_EQ(cli.exit_code, 1) << cli.output;
    EXPECT_EQ(cli.output.rfind("error: ", 0), 0u) << cli.output;
    EXPECT_NE(cli.output.find(file), std::string::npos) << cli.output;
  }

  testing::TempDir dir_{"malformed"};
};

TEST_F(MalformedModel, MissingFolder) {
  ExpectError("nothing_here", "nothing_here", "no such folder",
              /*check_cli=*/true);
}

TEST_F(MalformedModel, FolderWithoutModel) {
  fs::create_directories(dir_ / "empty");
  ExpectError("empty", "empty", "no COLMAP model");
}

TEST_F(MalformedModel, MissingPoints3DFile) {
  fs::remove(dir_ / "points3D.bin");
  ExpectError("", "points3D.bin", "missing", /*check_cli=*/true);
}

TEST_F(MalformedModel, TruncatedBinaries) {
  for (const char* file : {"cameras.bin", "images.bin", "points3D.bin"}) {
    const std::string bytes = Bytes(file);
    Put(file, bytes.substr(0, bytes.size() / 2 + 3));
    ExpectError("", file, "truncated");
    Put(file, bytes);
  }
}

TEST_F(MalformedModel, EmptyBinary) {
  Put("images.bin", "");
  ExpectError("", "images.bin", "truncated");
}

TEST_F(MalformedModel, GarbageBinary) {
  std::string garbage(5000, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = char(i * 131 + 7);
  Put("images.bin", garbage);
  ExpectError("", "images.bin", "images.bin: ");
}

TEST_F(MalformedModel, AbsurdPointCountDoesNotAllocate) {
  Patch<uint64_t>("points3D.bin", 0, 1000000000000ull);
  // Refused by the size check before any reserve: the message names the count.
  ExpectError("", "points3D.bin", "claims 1000000000000 points3D",
              /*check_cli=*/true);
}

TEST_F(MalformedModel, AbsurdPoints2DCount) {
  // First image record: id(4) qvec(32) tvec(24) camera(4) name+NUL.
  const std::string bytes = Bytes("images.bin");
  const size_t name_end = bytes.find('\0', 8 + 4 + 32 + 24 + 4);
  Patch<uint64_t>("images.bin", name_end + 1, uint64_t(1) << 50);
  ExpectError("", "images.bin", "claims 1125899906842624 points2D");
}

TEST_F(MalformedModel, TrailingBytes) {
  Put("cameras.bin", Bytes("cameras.bin") + "xyz");
  ExpectError("", "cameras.bin", "3 unexpected bytes");
}

TEST_F(MalformedModel, NaNInBinary) {
  Patch<double>("points3D.bin", 8 + 8, std::nan(""));
  ExpectError("", "points3D.bin", "xyz is not finite");
}

TEST_F(MalformedModel, InfInBinaryPose) {
  Patch<double>("images.bin", 8 + 4 + 32, INFINITY);
  ExpectError("", "images.bin", "tvec is not finite");
}

TEST_F(MalformedModel, NaNAndInfInText) {
  const std::string points = Bytes("txt/points3D.txt");
  Replace("txt/points3D.txt", "\n", "\n1 nan 0 0 1 2 3 -1\n");
  ExpectError("txt", "points3D.txt", "xyz is not finite");
  Put("txt/points3D.txt", points);
  Replace("txt/cameras.txt", "PINHOLE 64 48 ", "PINHOLE 64 48 inf ");
  ExpectError("txt", "cameras.txt", "parameter is not finite");
}

TEST_F(MalformedModel, ImplausibleImageSize) {
  Patch<uint64_t>("cameras.bin", 8 + 4 + 4, uint64_t(1) << 40);
  ExpectError("", "cameras.bin", "implausible image size 1099511627776x48");
  Replace("txt/cameras.txt", "PINHOLE 64 48", "PINHOLE 0 48");
  ExpectError("txt", "cameras.txt", "implausible image size 0x48");
}

TEST_F(MalformedModel, UnknownCameraModelIdInBinary) {
  Patch<int32_t>("cameras.bin", 8 + 4, 11);
  ExpectError("", "cameras.bin", "unknown camera model id 11");
}

TEST_F(MalformedModel, UnknownCameraModelNameInText) {
  Replace("txt/cameras.txt", "OPENCV", "OPENCV_X");
  ExpectError("txt", "cameras.txt", "unknown camera model `OPENCV_X`",
              /*check_cli=*/true);
}

TEST_F(MalformedModel, WrongParamCount) {
  Replace("txt/cameras.txt", "PINHOLE 64 48 ", "PINHOLE 64 48 1 ");
  ExpectError("txt", "cameras.txt", "takes 4 params");
}

TEST_F(MalformedModel, ImagePointsToMissingCamera) {
  Replace("txt/images.txt", " 2 frame_", " 99 frame_");
  ExpectError("txt", "images.txt", "camera 99 does not exist",
              /*check_cli=*/true);
}

TEST_F(MalformedModel, DuplicateCameraId) {
  Replace("txt/cameras.txt", "\n5 OPENCV", "\n2 OPENCV");
  ExpectError("txt", "cameras.txt", "duplicate camera 2");
}

TEST_F(MalformedModel, DuplicateImageId) {
  Replace("txt/images.txt", "\n12 ", "\n5 ");
  ExpectError("txt", "images.txt", "duplicate image 5");
}

TEST_F(MalformedModel, DuplicatePoint3DId) {
  const std::string text = Bytes("txt/points3D.txt");
  const size_t first = text.find('\n', text.find("# Number")) + 1;
  const std::string line =
      text.substr(first, text.find('\n', first) - first + 1);
  Put("txt/points3D.txt", text + line);
  ExpectError("txt", "points3D.txt", "duplicate point3D");
}

TEST_F(MalformedModel, TrackRefersToMissingImage) {
  Replace("txt/points3D.txt", "\n", "\n424242 0 0 0 1 2 3 0.5 77 0\n");
  ExpectError("txt", "points3D.txt", "track refers to missing image 77");
}

TEST_F(MalformedModel, TrackRefersToMissingPoint2D) {
  Replace("txt/points3D.txt", "\n", "\n424242 0 0 0 1 2 3 0.5 5 100000\n");
  ExpectError("txt", "points3D.txt", "track refers to point2D 100000");
}

TEST_F(MalformedModel, ImagesTextMissingPoints2DLine) {
  std::string text = Bytes("txt/images.txt");
  text.resize(text.rfind('\n', text.size() - 2) + 1);
  Put("txt/images.txt", text);
  ExpectError("txt", "images.txt", "lacks its POINTS2D line");
}

TEST_F(MalformedModel, BadNumberInText) {
  Replace("txt/points3D.txt", "\n", "\n12x 0 0 0 1 2 3 0.5\n");
  ExpectError("txt", "points3D.txt", "line 2: bad point3D id `12x`");
}

TEST_F(MalformedModel, ColorOutOfRange) {
  Replace("txt/points3D.txt", "\n", "\n424242 0 0 0 1 256 3 0.5\n");
  ExpectError("txt", "points3D.txt", "bad color `256`");
}

}  // namespace
}  // namespace watergs
