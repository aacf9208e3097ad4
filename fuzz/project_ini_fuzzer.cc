// libFuzzer target: `--project_path` .ini files (plugin/option_parser.h),
// parsed against options of each kind the commands register.
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz/fuzz_support.h"
#include "plugin/option_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::string ini = fuzz::WriteScratchFile("project.ini", data, size);
  std::string model_path = "model.ply";
  std::string output_path;
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
  try {
    parser.Parse(static_cast<int>(argv.size()), argv.data());
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e);
  }
  return 0;
}
