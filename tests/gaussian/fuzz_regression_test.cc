// Fuzzer findings in the checkpoint and SOG readers (see
// tests/common/fuzz_regressions.h): each input is refused with a one-line
// error naming the file, or reads cleanly if it is marked *.valid. (The PLY
// reader has had no finding so far.)
#include <gtest/gtest.h>

#include "gaussian/checkpoint.h"
#include "gaussian/formats/sog_io.h"
#include "gaussian/util/file_util.h"
#include "tests/common/fuzz_regressions.h"

namespace watergs {
namespace {

TEST(FuzzRegression, CheckpointInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("checkpoint")) {
    testing::ExpectFuzzRegressionHandled(input, input,
                                         [&] { ReadCheckpoint(input); });
  }
}

// sog_fuzzer's findings, rewritten as bundles (the fuzzer also takes a split
// form; the decoder behind both is the same).
TEST(FuzzRegression, SogInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("sog")) {
    testing::ExpectFuzzRegressionHandled(input, input, [&] {
      const std::vector<uint8_t> bytes = ReadFileBytes(input);
      const GaussianModel model = DecodeSog(input, bytes.data(), bytes.size());
      EXPECT_EQ(model.CountNonFinite(), 0u);
    });
  }
}

}  // namespace
}  // namespace watergs
