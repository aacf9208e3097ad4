// `watergs model_info`: the figures `colmap model_analyzer` prints, for a
// sparse model folder or a workspace (.bin or .txt).
#include <iostream>

#include "plugin/command.h"
#include "plugin/model_analyzer.h"
#include "plugin/option_parser.h"
#include "plugin/reconstruction_io.h"

namespace {

int RunModelInfo(int argc, char** argv) {
  std::string input_path;
  watergs::OptionParser parser(
      "model_info",
      "Prints the summary of a COLMAP sparse model, as "
      "`colmap model_analyzer` does.");
  parser.AddRequired("input_path", &input_path,
                     "Sparse model folder, or a workspace holding sparse/0");
  if (!parser.Parse(argc, argv)) return 0;
  const std::string model_path = watergs::FindModelPath(input_path);
  const watergs::Reconstruction reconstruction =
      watergs::ReadReconstruction(model_path);
  std::cout << "Model: " << model_path << " ("
            << (watergs::DetectModelFormat(model_path) ==
                        watergs::ModelFormat::kBinary
                    ? "BIN"
                    : "TXT")
            << ")\n"
            << watergs::FormatModelSummary(
                   watergs::AnalyzeModel(reconstruction));
  return 0;
}

}  // namespace

WATERGS_COMMAND(model_info,
                "Prints a COLMAP model's summary (as colmap model_analyzer)",
                RunModelInfo);
