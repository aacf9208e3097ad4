// `watergs attack`: applies the 3D distortions of the fine-tuning layers to a
// PLY file, for robustness evaluation and for users checking their files.
#include <iostream>
#include <random>

#include "distortion/distortion_layer.h"
#include "gaussian/error.h"
#include "gaussian/ply_io.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"

namespace watergs {
namespace {

int RunAttack(int argc, char** argv) {
  std::string input_path, output_path, attacks;
  int seed = 0;
  OptionParser parser(
      "attack",
      "Distorts a 3DGS PLY as the 3D distortion layers do: Gaussian noise on "
      "positions (gn:SIGMA, scene units), dropout of a random fraction "
      "(dropout:P), or removal of a contiguous run in file order (crop:P). "
      "Several, comma-separated, are applied in order. The output keeps the "
      "input's PLY layout.");
  parser.AddRequired("input_path", &input_path, "PLY to distort");
  parser.AddRequired("attack", &attacks,
                     "identity | gn:SIGMA | dropout:P | crop:P [,...]");
  parser.AddRequired("output_path", &output_path, "Distorted PLY to write");
  parser.Add("seed", &seed, "Random seed");
  if (!parser.Parse(argc, argv)) return 0;
  if (input_path == output_path) {
    Fail("attack: --output_path must differ from --input_path");
  }
  const std::vector<DistortionSpec> specs = ParseDistortionList(attacks);
  PlyData ply = ReadPly(input_path);
  std::mt19937_64 rng(static_cast<uint64_t>(seed));
  // parent[i]: index in the input file of output Gaussian i.
  std::vector<int64_t> parent(ply.model.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = int64_t(i);
  GaussianModel model = std::move(ply.model);
  const size_t input_count = model.size();
  for (const DistortionSpec& spec : specs) {
    GaussianModel distorted;
    std::vector<uint32_t> source;
    MakeDistortionLayer(spec)->Apply(model, rng, &distorted, &source);
    std::vector<int64_t> composed(source.size());
    for (size_t i = 0; i < source.size(); ++i) composed[i] = parent[source[i]];
    parent = std::move(composed);
    model = std::move(distorted);
    std::cout << ToString(spec) << ": " << model.size() << " Gaussians\n";
  }
  ply.layout.RemapExtras(parent);
  WritePly(output_path, model, ply.layout);
  std::cout << "wrote " << output_path << " (" << model.size() << " of "
            << input_count << " Gaussians)\n";
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(attack,
                "Applies 3D distortions (noise, dropout, crop) to a PLY",
                watergs::RunAttack);
