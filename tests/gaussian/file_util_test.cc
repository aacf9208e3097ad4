#include "gaussian/util/file_util.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

std::string TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_file_util_" + name + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

TEST(FileUtil, AtomicWriteReplacesContent) {
  const std::string path = TempDir("replace") + "/a.bin";
  AtomicWriteFile(path, std::string("first"));
  AtomicWriteFile(path, std::string("second"));
  const auto bytes = ReadFileBytes(path);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "second");
}

// Commands refuse an output that is their input; the check must see through
// spellings, or "./a.ply" would overwrite "a.ply".
TEST(FileUtil, SamePathSeesThroughSpellingsAndLinks) {
  const std::string dir = TempDir("same");
  const std::string a = dir + "/a.ply", b = dir + "/b.ply";
  EXPECT_TRUE(SamePath(a, dir + "/./a.ply"));  // neither exists yet
  EXPECT_TRUE(SamePath(a, dir + "/sub/../a.ply"));
  EXPECT_FALSE(SamePath(a, b));
  AtomicWriteFile(a, std::string("x"));
  AtomicWriteFile(b, std::string("x"));
  EXPECT_TRUE(SamePath(a, dir + "//a.ply"));
  EXPECT_FALSE(SamePath(a, b));
  std::filesystem::create_symlink(a, dir + "/link.ply");
  EXPECT_TRUE(SamePath(dir + "/link.ply", a));
  EXPECT_FALSE(SamePath(dir + "/link.ply", b));
}

TEST(FileUtil, FailedWriterLeavesPreviousVersionAndNoTemporary) {
  const std::string dir = TempDir("fail");
  const std::string path = dir + "/a.bin";
  AtomicWriteFile(path, std::string("good"));
  EXPECT_THROW(AtomicWriteFile(path,
                               [](std::ostream& out) {
                                 out << "partial";
                                 throw std::runtime_error("writer died");
                               }),
               std::runtime_error);
  const auto bytes = ReadFileBytes(path);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "good");
  int entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    (void)e;
    ++entries;
  }
  EXPECT_EQ(entries, 1);
}

TEST(FileUtil, MissingFileNamesThePath) {
  try {
    ReadFileBytes("/nonexistent/watergs.bin");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/watergs.bin"),
              std::string::npos);
  }
}

TEST(FileUtil, MissingOutputFolderIsAnError) {
  EXPECT_THROW(AtomicWriteFile("/nonexistent/dir/x.bin", std::string("x")),
               Error);
}

}  // namespace
}  // namespace watergs
