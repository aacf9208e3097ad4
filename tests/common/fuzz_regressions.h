// Test helper shared by the module test executables: the inputs the fuzzers
// (fuzz/, scripts/fuzz.sh) found crashing, hanging or misreporting in a
// reader, kept under tests/data/fuzz_regressions/<target>/ so that the fixes
// stay. A file or folder named *.valid must read cleanly (its finding was
// undefined behaviour on a valid input, which the sanitizer build checks);
// every other one must be refused with a one-line watergs::Error.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs::testing {

// The regression inputs of one fuzz target, sorted; fails the test if none.
inline std::vector<std::string> FuzzRegressionInputs(
    const std::string& target) {
  const std::filesystem::path dir = std::filesystem::path(WATERGS_SOURCE_DIR) /
                                    "tests/data/fuzz_regressions" / target;
  std::vector<std::string> inputs;
  if (std::filesystem::is_directory(dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      inputs.push_back(entry.path().string());
    }
  }
  std::sort(inputs.begin(), inputs.end());
  EXPECT_FALSE(inputs.empty()) << "no regression inputs in " << dir;
  return inputs;
}

inline bool IsValidRegressionInput(const std::string& input) {
  return std::filesystem::path(input).extension() == ".valid";
}

// Runs `read` on a regression input: *.valid inputs must read, the others
// must raise a one-line Error whose message starts with `error_prefix`.
inline void ExpectFuzzRegressionHandled(const std::string& input,
                                        const std::string& error_prefix,
                                        const std::function<void()>& read) {
  SCOPED_TRACE(input);
  if (IsValidRegressionInput(input)) {
    EXPECT_NO_THROW(read());
    return;
  }
  try {
    read();
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_EQ(message.rfind(error_prefix, 0), 0u) << message;
  }
}

}  // namespace watergs::testing
