// Number parsing shared by the option and attack parsers.
#include "gaussian/text_util.h"

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

}  // namespace watergs
