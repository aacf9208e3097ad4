// Test helper shared by the reader tests: the one-line Error a reader raises
// for bad input, checked to start with the file's name.
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "gaussian/util/error.h"

namespace watergs::testing {

// The message of the Error `read` throws; fails the test if it throws none,
// if the message does not start with "<name>: " or if it spans lines.
inline std::string Refusal(const std::string& name,
                           const std::function<void()>& read) {
  try {
    read();
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(name + ": ", 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message;
  }
  ADD_FAILURE() << name << ": accepted";
  return "";
}

}  // namespace watergs::testing
