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

// `text` with control characters written as \xNN, so that an error quoting
// what a user typed or a file held stays on one line.
inline std::string Printable(const std::string& text) {
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      out += std::string("\\x") + kHex[byte >> 4] + kHex[byte & 15];
    } else {
      out += c;
    }
  }
  return out;
}

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
