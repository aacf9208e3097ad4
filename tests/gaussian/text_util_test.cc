// Tests of the shared number parser: the whole text must be one finite number.
#include "gaussian/util/text_util.h"

#include <gtest/gtest.h>

namespace watergs {
namespace {

TEST(ParseFiniteDouble, AcceptsWholeFiniteNumbers) {
  EXPECT_EQ(ParseFiniteDouble("0.5"), 0.5);
  EXPECT_EQ(ParseFiniteDouble("-1e-3"), -1e-3);
  EXPECT_EQ(ParseFiniteDouble("2"), 2.0);
  EXPECT_EQ(ParseFiniteDouble("1e308"), 1e308);
}

TEST(ParseFiniteDouble, RefusesPartialNonFiniteAndOutOfRange) {
  for (const char* text : {"", " ", "1x", "0.5 ", "x1", "nan", "inf", "-inf",
                           "1e999", "--1", "1,5", "\n"}) {
    EXPECT_FALSE(ParseFiniteDouble(text).has_value()) << "'" << text << "'";
  }
}

}  // namespace
}  // namespace watergs
