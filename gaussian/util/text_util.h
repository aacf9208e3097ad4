// Text parsing shared by every option and attack parser: one definition of
// "a number" (the whole text, finite), so that all of them accept and refuse
// the same spellings.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace watergs {

// The value of `text` if the whole of it is one finite number (std::stod
// syntax: "0.5", "-1e-3", " 2" with leading blanks); nullopt otherwise
// ("", "1x", "nan", "inf", "1e999").
std::optional<double> ParseFiniteDouble(const std::string& text);

// The non-empty entries of a `sep`-separated list ("a,,b" -> {"a", "b"}).
std::vector<std::string> SplitList(const std::string& text, char sep = ',');

}  // namespace watergs
