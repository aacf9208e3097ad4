// Error reporting shared by every module: one exception type whose message is
// the single line the CLI prints ("<file>: <problem>").
#pragma once

#include <stdexcept>
#include <string>

namespace watergs {

// Raised for bad input, bad options and failed I/O; never for programming
// errors.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Throws Error("<path>: <problem>").
[[noreturn]] inline void FailAt(const std::string& path,
                                const std::string& problem) {
  throw Error(path + ": " + problem);
}

// Throws Error(message).
[[noreturn]] inline void Fail(const std::string& message) {
  throw Error(message);
}

}  // namespace watergs
