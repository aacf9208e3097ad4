// Fuzzer findings in the similarity-transform parser (see
// tests/common/fuzz_regressions.h): each input is refused with a one-line
// error.
#include <gtest/gtest.h>

#include <Eigen/LU>

#include "distortion/file_attacks.h"
#include "gaussian/util/file_util.h"
#include "tests/common/fuzz_regressions.h"

namespace watergs {
namespace {

TEST(FuzzRegression, SimilarityInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("similarity")) {
    const std::vector<uint8_t> bytes = ReadFileBytes(input);
    const std::string text(bytes.begin(), bytes.end());
    testing::ExpectFuzzRegressionHandled(input, "--attack: similarity:", [&] {
      const SimilarityTransform t = ParseSimilarity(text);
      // A *.valid input once parsed to something other than a rotation.
      EXPECT_TRUE(t.rotation.allFinite());
      EXPECT_NEAR(t.rotation.determinant(), 1.0, 1e-9);
      EXPECT_TRUE((t.rotation.transpose() * t.rotation).isIdentity(1e-9));
    });
  }
}

}  // namespace
}  // namespace watergs
