// Number parsing shared by the option and attack parsers.
#include "gaussian/util/text_util.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace watergs {

std::optional<double> ParseFiniteDouble(const std::string& text) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::logic_error&) {  // invalid_argument, out_of_range
    return std::nullopt;
  }
  if (used != text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

std::vector<std::string> SplitList(const std::string& text, char sep) {
  std::vector<std::string> entries;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(sep, start), text.size());
    if (end > start) entries.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return entries;
}

}  // namespace watergs
