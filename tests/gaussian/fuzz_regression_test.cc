// Fuzzer findings in the checkpoint reader (see
// tests/common/fuzz_regressions.h): each input is refused with a one-line
// error naming the file, or reads cleanly if it is marked *.valid. (The PLY
// reader has had no finding so far.)
#include <gtest/gtest.h>

#include "gaussian/checkpoint.h"
#include "tests/common/fuzz_regressions.h"

namespace watergs {
namespace {

TEST(FuzzRegression, CheckpointInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("checkpoint")) {
    testing::ExpectFuzzRegressionHandled(input, input,
                                         [&] { ReadCheckpoint(input); });
  }
}

}  // namespace
}  // namespace watergs
