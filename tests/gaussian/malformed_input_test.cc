// Malformed input and hostile output conditions for the files of gaussian/
// (PLY, checkpoints) and for AtomicWriteFile: every byte-prefix truncation,
// counts that disagree with the data or would need terabytes, NaN/Inf,
// non-ASCII paths, an output folder that cannot exist or is read-only, and a
// full disk. Each must give one Error line naming the file, and leave any
// previous output unchanged with no temporary behind.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "gaussian/checkpoint.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

class MalformedInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("watergs_malformed_gaussian_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add);
    fs::remove_all(dir_);
  }
  std::string Path(const std::string& name) const {
    return (dir_ / name).string();
  }
  // Plain write (no fsync: the cases are many and throwaway).
  static void Write(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  }
  static std::string Read(const std::string& path) {
    const std::vector<uint8_t> bytes = ReadFileBytes(path);
    return std::string(bytes.begin(), bytes.end());
  }
  // Names of the entries of `folder` (temporaries included).
  static std::vector<std::string> Entries(const std::string& folder) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(folder)) {
      names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
  fs::path dir_;
};

GaussianModel SmallModel(size_t n, int sh_degree) {
  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(n);
  std::mt19937 rng(9);
  std::normal_distribution<float> normal;
  for (ParamGroup g :
       {ParamGroup::kXyz, ParamGroup::kFDc, ParamGroup::kFRest,
        ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation}) {
    for (float& v : GroupParams(model, g)) v = normal(rng);
  }
  return model;
}

// `read(path)` throws one Error line that starts with the path and contains
// `problem`; returns the message.
template <typename ReadFn>
std::string ExpectError(ReadFn read, const std::string& path,
                        const std::string& problem) {
  try {
    read(path);
    ADD_FAILURE() << path << " was accepted; expected " << problem;
    return "";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(problem), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    return what;
  }
}

const auto kReadPly = [](const std::string& p) { ReadPly(p); };
const auto kReadCheckpoint = [](const std::string& p) { ReadCheckpoint(p); };

TEST_F(MalformedInput, PlyTruncatedAtEveryByte) {
  // Every prefix of a binary PLY (3 vertices, SH degree 1), hence every
  // header line and vertex/property boundary, is refused.
  const std::string good = Path("good.ply");
  WritePly(good, SmallModel(3, 1));
  const std::string bytes = Read(good);
  const size_t header_end = bytes.find("end_header\n") + 11;
  const std::string cut = Path("cut.ply");
  for (size_t keep = 0; keep < bytes.size(); ++keep) {
    Write(cut, bytes.substr(0, keep));
    SCOPED_TRACE(keep);
    // Inside the vertex data the problem is named as such.
    ExpectError(kReadPly, cut, keep >= header_end ? "truncated" : "");
  }
}

TEST_F(MalformedInput, AsciiPlyTruncatedAtEveryLine) {
  PlyLayout layout = InriaPlyLayout(0, 4);
  layout.format = PlyFormat::kAscii;
  const std::string good = Path("ascii.ply");
  WritePly(good, SmallModel(4, 0), layout);
  const std::string text = Read(good);
  const std::string cut = Path("cut.ply");
  for (size_t at = text.find('\n'); at + 1 < text.size();
       at = text.find('\n', at + 1)) {
    Write(cut, text.substr(0, at + 1));
    SCOPED_TRACE(at);
    ExpectError(kReadPly, cut, "");
  }
}

TEST_F(MalformedInput, PlyVertexCountDisagreesWithData) {
  const std::string good = Path("good.ply");
  WritePly(good, SmallModel(4, 0));
  const std::string bytes = Read(good);
  auto with_count = [&](const std::string& count) {
    std::string b = bytes;
    const size_t at = b.find("element vertex 4");
    b.replace(at, 16, "element vertex " + count);
    const std::string path = Path("count_" + count + ".ply");
    AtomicWriteFile(path, b);
    return path;
  };
  // More vertices than the data holds, up to counts needing terabytes: no
  // allocation, the message gives both sizes.
  ExpectError(kReadPly, with_count("5"), "declares 5 vertices");
  ExpectError(kReadPly, with_count("4000000000000"),
              "declares 4000000000000 vertices");
  // Fewer vertices than the data holds: the rest is not silently dropped.
  ExpectError(kReadPly, with_count("3"), "bytes after");
}

TEST_F(MalformedInput, CheckpointTruncatedAtEveryByte) {
  TrainingCheckpoint c;
  c.iteration = 20;
  c.model = SmallModel(2, 0);
  c.density_state = "state";
  c.rng_state = "rng";
  c.view_stack = {1, 0};
  c.run_signature = "{}";
  const std::string good = Path("good.ckpt");
  WriteCheckpoint(good, c);
  const std::string bytes = Read(good);
  const std::string cut = Path("cut.ckpt");
  for (size_t keep = 0; keep < bytes.size(); ++keep) {
    Write(cut, bytes.substr(0, keep));
    SCOPED_TRACE(keep);
    ExpectError(kReadCheckpoint, cut, "");
  }
}

// Checkpoint bytes with the u64 at `offset` replaced and the checksum
// recomputed (so that the length check itself is reached).
std::string Patched(std::string bytes, size_t offset, uint64_t value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(value));
  const uint64_t sum = Fnv1a64(bytes.data(), bytes.size() - 8);
  std::memcpy(bytes.data() + bytes.size() - 8, &sum, sizeof(sum));
  return bytes;
}

TEST_F(MalformedInput, CheckpointCountsAndNonFiniteValues) {
  TrainingCheckpoint c;
  c.model = SmallModel(2, 0);
  const std::string good = Path("good.ckpt");
  WriteCheckpoint(good, c);
  const std::string bytes = Read(good);
  // magic(8) version(4) iteration(8) sh(4) elapsed(8) sh_degree(4), then
  // the length of the means.
  const size_t means_length = 8 + 4 + 8 + 4 + 8 + 4;
  const std::string path = Path("bad.ckpt");
  AtomicWriteFile(path, Patched(bytes, means_length, uint64_t(1) << 40));
  ExpectError(kReadCheckpoint, path, "bad length");
  AtomicWriteFile(path, Patched(bytes, means_length, 5));
  ExpectError(kReadCheckpoint, path, "");
  // A NaN parameter with a valid checksum would poison training on resume.
  std::string nan = bytes;
  const float value = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data() + means_length + 8 + 4, &value, sizeof(value));
  const uint64_t sum = Fnv1a64(nan.data(), nan.size() - 8);
  std::memcpy(nan.data() + nan.size() - 8, &sum, sizeof(sum));
  AtomicWriteFile(path, nan);
  ExpectError(kReadCheckpoint, path, "not finite");
}

TEST_F(MalformedInput, NonAsciiPathsWork) {
  const std::string folder = Path("données_日本/モデル");
  CreateDirectories(folder);
  const GaussianModel model = SmallModel(5, 1);
  WritePly(folder + "/点群.ply", model);
  EXPECT_EQ(ReadPly(folder + "/点群.ply").model.means, model.means);
  TrainingCheckpoint c;
  c.model = model;
  WriteCheckpoint(folder + "/état.ckpt", c);
  EXPECT_EQ(ReadCheckpoint(folder + "/état.ckpt").model.sh_dc, model.sh_dc);
  // Errors name the path as given.
  ExpectError(kReadPly, folder + "/無い.ply", "not found");
}

TEST_F(MalformedInput, OutputFolderThatCannotExist) {
  // A path whose parent is a regular file: fails even as root.
  const std::string file = Path("a_file");
  AtomicWriteFile(file, std::string("x"));
  const std::string target = file + "/out.ply";
  ExpectError([](const std::string& p) { WritePly(p, SmallModel(2, 0)); },
              target, "does not exist");
  ExpectError([](const std::string& p) { CreateDirectories(p); }, file + "/sub",
              "cannot create folder");
  EXPECT_EQ(Entries(dir_.string()), std::vector<std::string>{"a_file"});
}

TEST_F(MalformedInput, ReadOnlyOutputFolder) {
  if (::geteuid() == 0) {
    GTEST_SKIP() << "running as root, which ignores folder permissions (the "
                    "not-a-folder case above covers root)";
  }
  const std::string folder = Path("read_only");
  CreateDirectories(folder);
  AtomicWriteFile(folder + "/out.ply", std::string("previous"));
  fs::permissions(folder, fs::perms::owner_read | fs::perms::owner_exec);
  ExpectError([](const std::string& p) { WritePly(p, SmallModel(2, 0)); },
              folder + "/out.ply", "cannot write");
  fs::permissions(folder, fs::perms::owner_all);
  EXPECT_EQ(Read(folder + "/out.ply"), "previous");
  EXPECT_EQ(Entries(folder), std::vector<std::string>{"out.ply"});
}

TEST_F(MalformedInput, TemporariesOfDeadWritersAreRemovedOnTheNextWrite) {
  // What a writer killed mid-write leaves: `<path>.tmp.<pid>.<hex>`. A pid
  // that no longer runs: a reaped child's.
  const pid_t child = fork();
  if (child == 0) _exit(0);
  int status = 0;
  waitpid(child, &status, 0);
  const std::string out = Path("out.ply");
  const std::string dead = out + ".tmp." + std::to_string(child) + ".abc";
  const std::string live = out + ".tmp." + std::to_string(::getpid()) + ".def";
  const std::string other = Path("other.ply.tmp.") + std::to_string(child);
  for (const std::string& p : {dead, live, other}) Write(p, "partial");
  AtomicWriteFile(out, std::string("complete"));
  EXPECT_EQ(Read(out), "complete");
  EXPECT_FALSE(fs::exists(dead));
  EXPECT_TRUE(fs::exists(live));   // a running writer's is kept
  EXPECT_TRUE(fs::exists(other));  // another output's is not touched
}

TEST_F(MalformedInput, FullDiskKeepsThePreviousOutput) {
  // A disk that fills up mid-write, simulated in a child process by a file
  // size limit of 16 KiB (writes past it fail with EFBIG, SIGXFSZ ignored).
  const std::string ply = Path("out.ply"), ckpt = Path("out.ckpt");
  AtomicWriteFile(ply, std::string("previous ply"));
  AtomicWriteFile(ckpt, std::string("previous checkpoint"));
  int pipe_fds[2];
  ASSERT_EQ(pipe(pipe_fds), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    close(pipe_fds[0]);
    std::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{16 << 10, 16 << 10};
    setrlimit(RLIMIT_FSIZE, &limit);
    std::string messages;
    const GaussianModel big = SmallModel(2000, 1);  // ~ 250 KB as PLY
    try {
      WritePly(ply, big);
    } catch (const Error& e) {
      messages += std::string(e.what()) + "\n";
    }
    try {
      TrainingCheckpoint c;
      c.model = big;
      WriteCheckpoint(ckpt, c);
    } catch (const Error& e) {
      messages += std::string(e.what()) + "\n";
    }
    [[maybe_unused]] ssize_t n =
        write(pipe_fds[1], messages.data(), messages.size());
    _exit(0);
  }
  close(pipe_fds[1]);
  std::string messages;
  char buffer[4096];
  ssize_t n;
  while ((n = read(pipe_fds[0], buffer, sizeof(buffer))) > 0) {
    messages.append(buffer, n);
  }
  close(pipe_fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "the writer crashed";
  // Two one-line errors, each naming its file and the failed write.
  const size_t first_end = messages.find('\n');
  ASSERT_NE(first_end, std::string::npos) << messages;
  const std::string first = messages.substr(0, first_end);
  const std::string second = messages.substr(first_end + 1);
  EXPECT_EQ(first.rfind(ply + ": write failed", 0), 0u) << first;
  EXPECT_EQ(second.rfind(ckpt + ": write failed", 0), 0u) << second;
  EXPECT_EQ(std::count(second.begin(), second.end(), '\n'), 1) << second;
  EXPECT_EQ(Read(ply), "previous ply");
  EXPECT_EQ(Read(ckpt), "previous checkpoint");
  EXPECT_EQ(Entries(dir_.string()),
            (std::vector<std::string>{"out.ckpt", "out.ply"}));
}

}  // namespace
}  // namespace watergs
