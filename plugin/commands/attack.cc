// `watergs attack`: applies the 3D distortions of the fine-tuning layers and
// the file attacks users meet (SH truncation, quantisation, shuffling, a
// similarity transform, opacity pruning, the real encoders and decoders of
// .spz, compressed PLY, .splat and SOG) to a model, for robustness evaluation
// and for users checking their files. The input may be in any format the model
// loader reads; the output's format follows its extension (.spz, .splat,
// .compressed.ply, .sog; anything else is a PLY in the input's layout, Inria's
// for a non-PLY input). A similarity transform moves the scene
// away from the workspace's cameras: the transform is printed and written to
// <output_path>.transform.txt for `watergs extract --scene_transform`.
// prune_significance renders the scene from the workspace's training
// cameras (--workspace_path), as LightGaussian scores Gaussians.
#include <iostream>
#include <random>

#include "distortion/file_attacks.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "plugin/workspace.h"

namespace watergs {
namespace {

int RunAttack(int argc, char** argv) {
  std::string input_path, output_path, attacks;
  WorkspaceOptions workspace_options;
  workspace_options.images_optional = true;  // cameras only
  int seed = 0;
  OptionParser parser(
      "attack",
      "Attacks a 3DGS PLY, applying the comma-separated attacks in order: "
      "gn:SIGMA (noise on positions, scene units), dropout:P (random "
      "fraction removed), crop:P (contiguous run in file order removed), sh0 "
      "(f_rest zeroed: degree-0 colour, layout kept), fp16 (attributes "
      "rounded to float16), quant:BITS (per-attribute min/max linear "
      "quantisation, default 8), shuffle (Gaussians permuted), "
      "similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ] (whole scene rotated about the "
      "axis, default z, scaled and translated; SH rotated with it), prune:T "
      "(Gaussians with opacity < T removed), spz[:2|3], compressed_ply, "
      "splat, sog (a round trip through that format's encoder and decoder), "
      "prune_significance:F (the fraction F of lowest LightGaussian "
      "significance removed; needs --workspace_path), decimate:F (nearest "
      "neighbours merged until F of the Gaussians are gone), "
      "quant_chunk:BITS[:POSBITS] (per chunk of 256 Morton-ordered "
      "Gaussians, min/max quantisation; positions POSBITS, default 16). The "
      "input is any model file (PLY, compressed PLY, .spz, .splat, SOG); the "
      "output is written in the format its extension names (.spz, .splat, "
      ".sog, "
      ".compressed.ply), otherwise as a PLY in the input's layout.");
  parser.AddRequired(
      "input_path", &input_path,
      "Model to attack (PLY, compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("attack", &attacks,
                     "identity | gn:SIGMA | dropout:P | crop:P | sh0 | fp16 | "
                     "quant:BITS | shuffle | similarity:DEG,TX,TY,TZ,S[,AX,AY,"
                     "AZ] | prune:T | spz[:VERSION] | compressed_ply | splat "
                     "| sog | prune_significance:F | decimate:F | "
                     "quant_chunk:BITS[:POSBITS] [,...]");
  parser.AddRequired("output_path", &output_path,
                     "Attacked model to write (.spz, .splat, .sog, "
                     ".compressed.ply or a PLY)");
  parser.Add("seed", &seed, "Random seed");
  parser.Add("workspace_path", &workspace_options.workspace_path,
             "COLMAP workspace whose training cameras (all but every 8th "
             "view) prune_significance renders from");
  parser.Add("sparse_path", &workspace_options.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("downscale", &workspace_options.downscale,
             "Camera downscale for prune_significance: 1,2,4,8");
  if (!parser.Parse(argc, argv)) return 0;
  if (SamePath(input_path, output_path)) {
    Fail("attack: --output_path must differ from --input_path");
  }
  const std::vector<ModelAttackSpec> specs = ParseModelAttackList(attacks);
  std::vector<RenderCamera> cameras;
  for (const ModelAttackSpec& spec : specs) {
    if (!AttackNeedsCameras(spec) || !cameras.empty()) continue;
    if (workspace_options.workspace_path.empty() &&
        workspace_options.input_path.empty()) {
      Fail("attack: " + ToString(spec) +
           " renders the scene: give --workspace_path (the COLMAP workspace "
           "of its training cameras)");
    }
    const Workspace workspace = Workspace::Open(workspace_options);
    std::vector<size_t> views = workspace.TrainViews(true);
    if (views.empty()) views = workspace.TrainViews(false);  // one view
    for (size_t view : views) cameras.push_back(workspace.ViewCamera(view));
  }
  // Before the work: a missing output folder fails at once.
  CheckOutputFile(output_path);
  ModelData ply = ReadModelFile(input_path);
  std::mt19937_64 rng(static_cast<uint64_t>(seed));
  // parent[i]: index in the input file of output Gaussian i.
  std::vector<int64_t> parent(ply.model.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = int64_t(i);
  GaussianModel model = std::move(ply.model);
  const size_t input_count = model.size();
  SimilarityTransform scene_transform;
  bool moved = false;
  for (const ModelAttackSpec& spec : specs) {
    GaussianModel attacked;
    std::vector<uint32_t> source;
    ApplyModelAttack(spec, model, rng, &attacked, &source, &cameras);
    std::vector<int64_t> composed(source.size());
    for (size_t i = 0; i < source.size(); ++i) composed[i] = parent[source[i]];
    parent = std::move(composed);
    model = std::move(attacked);
    if (spec.kind == ModelAttackKind::kSimilarity) {
      scene_transform = spec.similarity.After(scene_transform);
      moved = true;
    }
    std::cout << ToString(spec) << ": " << model.size() << " Gaussians\n";
  }
  ply.layout.RemapExtras(parent);
  WriteModelFile(output_path, model, ply.layout);
  std::cout << "wrote " << output_path << " (" << model.size() << " of "
            << input_count << " Gaussians)\n";
  if (moved) {
    const std::string text = "similarity:" + ToString(scene_transform);
    AtomicWriteFile(output_path + ".transform.txt", text + "\n");
    std::cout << "scene transform " << text << "\nwrote " << output_path
              << ".transform.txt (pass it to extract --scene_transform)\n";
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(attack,
                "Attacks a model: 3D distortions, SH truncation, quantisation, "
                "shuffling, similarity transform, pruning, decimation, codecs",
                watergs::RunAttack);
