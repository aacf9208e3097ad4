// Fuzzer findings in the weights-file reader, the HiDDeN model loader and the
// message parser (see tests/common/fuzz_regressions.h): each input is refused
// with a one-line error, or handled cleanly if it is marked *.valid.
#include <gtest/gtest.h>

#include "gaussian/util/file_util.h"
#include "tests/common/fuzz_regressions.h"
#include "watermark/hidden_model.h"
#include "watermark/lpips.h"
#include "watermark/message.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

TEST(FuzzRegression, NetworkFileInputsAreHandled) {
  for (const std::string& input :
       testing::FuzzRegressionInputs("network_file")) {
    // A *.valid input is a file, not a model: its finding was in the reader.
    testing::ExpectFuzzRegressionHandled(input, input, [&] {
      const NetworkFile file = ReadNetworkFile(input);
      if (!testing::IsValidRegressionInput(input)) {
        HiddenModelFromFile(input, file, /*need_encoder=*/false);
      }
    });
  }
}

// A message input is the fuzzer's: one byte b choosing a 1 + 4 b bit
// decoder, then the text typed.
TEST(FuzzRegression, MessageInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("message")) {
    const std::vector<uint8_t> bytes = ReadFileBytes(input);
    ASSERT_FALSE(bytes.empty()) << input;
    const int num_bits = 1 + 4 * bytes[0];
    const std::string text(bytes.begin() + 1, bytes.end());
    testing::ExpectFuzzRegressionHandled(input, "message",
                                         [&] { ParseMessage(text, num_bits); });
  }
}

// LPIPS-VGG weights files (the CRC already matches, as the fuzzer made it).
TEST(FuzzRegression, LpipsWeightsInputsAreHandled) {
  for (const std::string& input :
       testing::FuzzRegressionInputs("lpips_weights")) {
    testing::ExpectFuzzRegressionHandled(input, input,
                                         [&] { Lpips::Load(input); });
  }
}

}  // namespace
}  // namespace watergs
