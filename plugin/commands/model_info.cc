// `watergs model_info`: the figures `colmap model_analyzer` prints, for a
// sparse model folder or a workspace (.bin or .txt); with a reference model
// of the same photos, how far its camera poses are from the reference's.
#include <cstdio>
#include <iostream>

#include "plugin/command.h"
#include "plugin/model_analyzer.h"
#include "plugin/option_parser.h"
#include "plugin/pose_comparison.h"
#include "plugin/poses_bounds.h"
#include "plugin/reconstruction_io.h"

namespace {

int RunModelInfo(int argc, char** argv) {
  std::string input_path, reference_path;
  watergs::OptionParser parser(
      "model_info",
      "Prints the summary of a COLMAP sparse model, as "
      "`colmap model_analyzer` does.");
  parser.AddRequired("sparse_path", &input_path,
                     "Sparse model folder, or a workspace holding sparse/0");
  parser.AddAlias("input_path", "sparse_path");
  parser.Add("reference_path", &reference_path,
             "A model of the same photos (e.g. from known poses), or an LLFF "
             "poses_bounds.npy (rows named by the sorted images/ beside it): "
             "print how far the camera poses are from it, up to a "
             "similarity");
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
  // Not a model_analyzer figure: how far neighbouring cameras sit apart.
  char baseline[96];
  std::snprintf(baseline, sizeof(baseline),
                "Neighbour baseline / depth: median %.4f\n",
                watergs::MedianNeighbourBaselineToDepth(reconstruction));
  std::cout << baseline;
  if (!reference_path.empty()) {
    const bool npy = reference_path.size() > 4 &&
                     reference_path.substr(reference_path.size() - 4) == ".npy";
    const watergs::Reconstruction reference =
        npy ? watergs::ReadPosesBounds(
                  reference_path,
                  watergs::PosesBoundsImageNames(reference_path))
            : watergs::ReadReconstruction(
                  watergs::FindModelPath(reference_path));
    std::cout << watergs::FormatPoseComparison(
        watergs::ComparePoses(reconstruction, reference));
  }
  return 0;
}

}  // namespace

WATERGS_COMMAND(model_info,
                "Prints a COLMAP model's summary (as colmap model_analyzer)",
                RunModelInfo);
