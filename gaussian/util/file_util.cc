#include "gaussian/util/file_util.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <utility>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {

uint64_t Fnv1a64(const void* data, size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  uint64_t hash = 0xcbf29ce484222325ull;
  for (size_t i = 0; i < size; ++i) {
    hash ^= p[i];
    hash *= 0x100000001b3ull;
  }
  return hash;
}
namespace {

std::string TemporaryPathFor(const std::string& path) {
  std::random_device rd;
  std::ostringstream name;
  name << path << ".tmp." << ::getpid() << "." << std::hex << rd();
  return name.str();
}

// fsync of `path` opened with `flags`; returns 0 or the errno of a failure.
int FsyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags);
  if (fd < 0) return errno;
  const int error = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  return error;
}

// Removes `<target>.tmp.<pid>.*` files whose writer no longer runs: a
// process killed inside AtomicWriteFile (SIGKILL, power loss) cannot remove
// its temporary, and the next successful write of the same target does.
void RemoveStaleTemporaries(const std::filesystem::path& target,
                            const std::filesystem::path& dir) {
  const std::string prefix = target.filename().string() + ".tmp.";
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code ignored;
      std::filesystem::remove(it->path(), ignored);
    }
  }
}

}  // namespace

std::vector<uint8_t> ReadFileBytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) FailAt(path, "file not found");
  if (std::filesystem::is_directory(path, ec)) {
    FailAt(path, "is a directory, expected a file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) FailAt(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (in.bad()) FailAt(path, "read error");
  return bytes;
}

namespace {

// The folder `path` is written into ("." for a bare name).
std::filesystem::path FolderOf(const std::string& path) {
  const std::filesystem::path target(path);
  return target.has_parent_path() ? target.parent_path() : ".";
}

// Fills a new temporary next to `path` with `writer`, flushed and fsync'ed;
// returns its name. On any failure the temporary is removed and Error names
// `path`.
std::string WriteTemporary(const std::string& path,
                           const std::function<void(std::ostream&)>& writer) {
  std::error_code ec;
  CheckOutputFile(path);
  const std::string tmp = TemporaryPathFor(path);
  try {
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      if (!out) {
        FailAt(path, std::string("cannot write: ") + std::strerror(errno));
      }
      writer(out);
      out.flush();
      if (!out) {
        FailAt(path, std::string("write failed (disk full?): ") +
                         std::strerror(errno));
      }
    }
    // Delayed allocation can report a full disk only here; folders and
    // filesystems that cannot fsync at all (EINVAL) are fine.
    const int sync_error = FsyncPath(tmp, O_RDONLY);
    if (sync_error == EIO || sync_error == ENOSPC || sync_error == EDQUOT) {
      FailAt(path,
             std::string("cannot flush to disk: ") + std::strerror(sync_error));
    }
  } catch (...) {
    std::filesystem::remove(tmp, ec);
    throw;
  }
  return tmp;
}

// Renames a finished temporary over `path` and syncs the folder.
void CommitTemporary(const std::string& tmp, const std::string& path) {
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    FailAt(path, "cannot rename temporary into place: " + ec.message());
  }
  FsyncPath(FolderOf(path).string(), O_RDONLY | O_DIRECTORY);
  RemoveStaleTemporaries(path, FolderOf(path));
}

}  // namespace

void AtomicWriteFile(const std::string& path,
                     const std::function<void(std::ostream&)>& writer) {
  CommitTemporary(WriteTemporary(path, writer), path);
}

void AtomicWriteFiles(
    const std::vector<std::pair<std::string, std::string>>& files) {
  // Every target is checked and every temporary written before any file is
  // replaced: a failure on the last file leaves all of them as they were.
  std::vector<std::string> temporaries;
  try {
    // (Not a structured binding: clang 14, the fuzz build's compiler, cannot
    // capture one in a lambda.)
    for (const auto& file : files) {
      const std::string& bytes = file.second;
      temporaries.push_back(WriteTemporary(file.first, [&](std::ostream& out) {
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      }));
    }
    for (size_t k = 0; k < files.size(); ++k) {
      CommitTemporary(temporaries[k], files[k].first);
      temporaries[k].clear();
    }
  } catch (...) {
    std::error_code ec;
    for (const std::string& tmp : temporaries) {
      if (!tmp.empty()) std::filesystem::remove(tmp, ec);
    }
    throw;
  }
}

void AtomicWriteFile(const std::string& path, const std::string& bytes) {
  AtomicWriteFile(path, [&](std::ostream& out) {
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  });
}

void CheckOutputFile(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path dir = FolderOf(path);
  if (!std::filesystem::is_directory(dir, ec)) {
    FailAt(path, "output folder " + dir.string() + " does not exist");
  }
  if (std::filesystem::is_directory(path, ec)) {
    FailAt(path, "is a directory, expected a file");
  }
  if (::access(dir.c_str(), W_OK) != 0) {
    FailAt(path, "output folder " + dir.string() +
                     " is not writable: " + std::strerror(errno));
  }
}

void CreateDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) FailAt(path, "cannot create folder: " + ec.message());
}

bool SamePath(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::equivalent(a, b, ec) && !ec) return true;
  const fs::path ca = fs::weakly_canonical(a, ec);
  if (ec) return a == b;
  const fs::path cb = fs::weakly_canonical(b, ec);
  if (ec) return a == b;
  return ca == cb;
}

}  // namespace watergs
