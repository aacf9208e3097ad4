// Fuzzer findings in the COLMAP model readers and the --project_path .ini
// parser (see tests/common/fuzz_regressions.h): each input is refused with a
// one-line error, or read cleanly if it is marked *.valid. A COLMAP input is
// a model folder (the fuzzed file and the two files it was read with).
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "plugin/option_parser.h"
#include "plugin/reconstruction_io.h"
#include "tests/common/fuzz_regressions.h"

namespace watergs {
namespace {

TEST(FuzzRegression, ColmapModelInputsAreHandled) {
  for (const std::string& input : testing::FuzzRegressionInputs("colmap_bin")) {
    testing::ExpectFuzzRegressionHandled(input, input,
                                         [&] { ReadReconstruction(input); });
  }
}

// The options of fuzz/project_ini_fuzzer.cc, one of each kind.
void ParseProjectFile(const std::string& ini) {
  std::string model_path = "model.ply", output_path;
  int iterations = 30000;
  int64_t seed = 0;
  double lambda = 0.2;
  bool quiet = false;
  OptionParser parser("fuzz", "Options of every kind, read from an .ini.");
  parser.Add("model_path", &model_path, "string option");
  parser.Add("iterations", &iterations, "int option");
  parser.Add("seed", &seed, "int64 option");
  parser.Add("lambda", &lambda, "double option");
  parser.AddFlag("quiet", &quiet, "flag");
  parser.AddRequired("output_path", &output_path, "required option");
  std::vector<std::string> args = {"fuzz", "--project_path", ini};
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  parser.Parse(static_cast<int>(argv.size()), argv.data());
}

TEST(FuzzRegression, ProjectFileInputsAreHandled) {
  for (const std::string& input :
       testing::FuzzRegressionInputs("project_ini")) {
    testing::ExpectFuzzRegressionHandled(input, input,
                                         [&] { ParseProjectFile(input); });
  }
}

}  // namespace
}  // namespace watergs
