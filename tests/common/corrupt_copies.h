// Test helper: a weights file whose copy has one flipped bit or a cut tail
// must be refused by its loader with an error that starts with the copy's
// path.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs::testing {

inline void ExpectCorruptCopiesRefused(
    const std::string& path,
    const std::function<void(const std::string&)>& load) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_corrupt_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string copy_path =
      (dir / std::filesystem::path(path).filename()).string();
  auto expect_refused = [&](const std::vector<uint8_t>& copy,
                            const char* what) {
    AtomicWriteFile(copy_path, std::string(copy.begin(), copy.end()));
    try {
      load(copy_path);
      ADD_FAILURE() << what << " copy was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(copy_path + ": ", 0), 0u)
          << e.what();
    }
  };
  std::vector<uint8_t> flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x01;
  expect_refused(flipped, "bit-flipped");
  expect_refused(std::vector<uint8_t>(bytes.begin(), bytes.end() - 100),
                 "truncated");
  std::filesystem::remove_all(dir);
}

}  // namespace watergs::testing
