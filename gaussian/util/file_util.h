// File helpers: whole-file reads and crash-safe (atomic) writes.
#pragma once

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

namespace watergs {

// FNV-1a 64-bit hash of `size` bytes, the standard function (offset basis
// 0xcbf29ce484222325, prime 0x100000001b3): the integrity checksum of
// checkpoints and network files, and the files' fingerprint in reports.
uint64_t Fnv1a64(const void* data, size_t size);

// Reads a whole file; throws Error("<path>: ...") if missing or unreadable.
std::vector<uint8_t> ReadFileBytes(const std::string& path);

// Writes `path` atomically: `writer` fills a temporary file in the same
// folder, which is flushed, fsync'ed and renamed over `path`. If `writer`
// throws or any write fails, the temporary is removed, `path` is untouched
// and Error("<path>: ...") is thrown. A successful write also removes the
// temporaries of `path` left by writers that no longer run (killed mid-write).
void AtomicWriteFile(const std::string& path,
                     const std::function<void(std::ostream&)>& writer);

// Convenience overload for an in-memory buffer.
void AtomicWriteFile(const std::string& path, const std::string& bytes);

// Writes several files (path, bytes) as a set: every temporary is written
// and fsync'ed before the first rename, so an error on any file (a full
// disk, a folder in the way) leaves all of them untouched. Only a crash
// during the renames themselves (microseconds) can leave a mix.
void AtomicWriteFiles(
    const std::vector<std::pair<std::string, std::string>>& files);

// Throws the Error that writing `path` would meet later: its folder missing
// or not writable, or a folder in its place. Commands check their outputs
// with it before the work, so that a mistyped path fails at once.
void CheckOutputFile(const std::string& path);

// Creates a directory and its parents; throws Error on failure.
void CreateDirectories(const std::string& path);

// True when two paths name the same file or folder however they are spelled
// ("a.ply", "./a.ply", a symlink to it); compares normalised absolute paths
// when either does not exist yet.
bool SamePath(const std::string& a, const std::string& b);

}  // namespace watergs
