// `watergs extract`: reads the WATER-GS watermark of a 3DGS model from its
// renders and, given the claimed message, prints the statistical verdict.
// A verdict is a result, not an error: the exit code is 0 for all of them.
// A model moved by a similarity transform (`watergs attack similarity:...`)
// is read from cameras moved with it (--scene_transform); renders can be
// attacked before decoding (--image_attack jpeg:Q | resize:F | crop:F).
#include <omp.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "distortion/file_attacks.h"
#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/rasterizer.h"
#include "gaussian/render_conventions.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"
#include "watermark/message.h"

namespace watergs {
namespace {

// The verdict lines of one reading (`label`: "" or " (owner's reading)").
void PrintVerdict(const ExtractionResult& r, const char* label,
                  double present_p) {
  std::printf(
      "extract%s: single views (%zu): BER mean %.2f%% median %.2f%% p90 "
      "%.2f%% (min %.2f%%, max %.2f%%)\n",
      label, r.views.size(), 100 * r.mean_view_ber, 100 * r.median_view_ber,
      100 * r.p90_view_ber, 100 * r.min_view_ber, 100 * r.max_view_ber);
  std::printf(
      "extract%s: aggregated over the %zu views (mean logits): BER %.2f%% (%d "
      "of %zu bits)\n",
      label, r.views.size(), 100 * r.ber, r.bit_errors, r.recovered.size());
  std::printf(
      "extract%s: p-value %.3g (chance of this many matching bits from an "
      "unmarked model)\n",
      label, r.p_value);
  std::printf("extract%s: verdict: %s (false-positive rate %.0e)\n", label,
              ToString(r.verdict).c_str(), present_p);
}

int RunExtract(int argc, char** argv) {
  std::string raw_path;
  std::string input_path, decoder_path, message, key_option, json_path;
  std::string scene_transform, image_attack;
  std::string background = "0,0,0";
  WorkspaceOptions workspace_options;
  int num_views = 0;
  int max_views = 0;
  std::string split = "all";
  int64_t seed = 0;
  int num_threads = 0;
  double present_p = VerificationThresholds().present_p;
  OptionParser parser(
      "extract",
      "Decodes the WATER-GS watermark of a 3DGS model from rendered views "
      "(logits averaged over views) and tests it against a claimed message: "
      "binomial p-value under the null hypothesis of an unmarked model; "
      "'watermark present' at p <= --false_positive_rate, 'absent' above "
      "p = 0.01, 'inconclusive' between.");
  parser.AddRequired(
      "input_path", &input_path,
      "3DGS model to examine (PLY, compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("workspace_path", &workspace_options.workspace_path,
                     "COLMAP workspace whose cameras are rendered");
  parser.Add("sparse_path", &workspace_options.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add(
      "image_path", &workspace_options.image_path,
      "Image folder (optional: a few photos check the model's frame, --align)");
  parser.Add("downscale", &workspace_options.downscale,
             "Image downscale: 1,2,4,8");
  std::string align = "auto";
  parser.Add("align", &align,
             std::string(kAlignHelp) +
                 " (the raw model's frame with --raw_path; without it, "
                 "--scene_transform replaces it)");
  decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &decoder_path, kDecoderHelp);
  parser.Add("raw_path", &raw_path,
             "The unwatermarked model (the owner's): also read each bit from "
             "the difference of the suspect's logits and this model's at the "
             "same viewpoint (the owner's reading, printed beside the blind "
             "one)");
  parser.Add("message", &message,
             std::string("Claimed message: ") + kMessageFormats);
  parser.Add("key", &key_option, kKeyHelp);
  parser.Add("num_views", &num_views,
             "Render N free viewpoints between the cameras (0 = the "
             "workspace's cameras)");
  parser.Add(
      "max_views", &max_views,
      "Use at most this many workspace cameras, spread evenly (0 = all)");
  parser.Add("split", &split,
             "Workspace cameras to render: all, train or test (test: every "
             "8th, the views train --split train and embed --split train hold "
             "out)");
  parser.Add("false_positive_rate", &present_p,
             "p-value at or below which the watermark is declared present");
  parser.Add("background", &background, "r,g,b, black or white");
  parser.Add("seed", &seed, "Seed of the free viewpoints");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  parser.Add("json", &json_path, "Write the result as JSON to this file");
  parser.Add("scene_transform", &scene_transform,
             "similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ] the model was moved by, or "
             "the .transform.txt file watergs attack wrote: the cameras move "
             "with it");
  parser.Add("image_attack", &image_attack,
             "Attack each render before decoding: jpeg:Q, resize:F, crop:F "
             "(a resized render is decoded at the camera's size again, as an "
             "owner decodes a smaller copy)");
  std::string conventions_name = "watergs";
  parser.Add("render_conventions", &conventions_name,
             "Read the views as another renderer shows them, the raw model's "
             "too (on the CPU whatever --device says): what that viewer's "
             "screenshot at the same camera carries, without a browser. " +
                 RenderConventionsHelp());
  if (!parser.Parse(argc, argv)) return 0;
  const RenderConventions conventions =
      FindRenderConventions(conventions_name, "--render_conventions")
          .conventions;
  if (num_views < 0 || max_views < 0) Fail("--num_views must be >= 0");
  if (split != "all" && split != "train" && split != "test") {
    Fail("--split: all, train or test");
  }
  if (num_views > 0 && split != "all") {
    Fail("--split selects workspace cameras; --num_views renders free ones");
  }
  if (!(present_p > 0 && present_p < 0.01)) {
    Fail("--false_positive_rate must be in (0, 0.01)");
  }
  if (num_threads > 0) omp_set_num_threads(num_threads);
  // Before the work: a mistyped --json path fails at once.
  if (!json_path.empty()) CheckOutputFile(json_path);

  const ModelData ply = ReadModelFile(input_path);
  ModelData raw;
  if (!raw_path.empty()) {
    if (SamePath(raw_path, input_path)) {
      Fail(
          "extract: --raw_path is the --input_path (the owner's reading "
          "compares two models)");
    }
    raw = ReadModelFile(raw_path);
  }
  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(decoder_path, parser.device());
  Bits expected;
  const std::string key = ResolveKey(key_option);
  if (!message.empty()) {
    expected = ApplyKey(ParseMessage(message, decoder->NumBits()), key);
  }
  workspace_options.images_optional = true;  // photos only check the frame
  const Workspace workspace = Workspace::Open(workspace_options);
  const WorkspaceViews workspace_views(workspace);
  // A suspect moved by a known transform is read through it, not searched.
  if (!scene_transform.empty() && raw_path.empty() && align == "auto") {
    align = "off";
  }
  const std::unique_ptr<Rasterizer> rasterizer =
      MakeRasterizer(parser.device());
  // With the owner's reading both models are in the raw model's frame.
  const PlacedViews placed = PlaceByOption(
      "extract", align, *rasterizer, raw_path.empty() ? ply.model : raw.model,
      raw_path.empty() ? input_path : raw_path, workspace, workspace_views,
      ParseBackground(background), /*suspect=*/raw_path.empty());
  const TrainingViews& views = placed.views();

  std::vector<RenderCamera> cameras;
  std::vector<std::string> names;
  if (num_views > 0) {
    cameras = SampleFreeViewpoints(views, num_views, uint64_t(seed));
  } else {
    const std::vector<size_t> pool =
        split == "test" ? workspace.TestViews(true)
                        : workspace.TrainViews(split == "train");
    if (pool.empty()) Fail("extract: --split " + split + " selects no camera");
    const size_t n = pool.size();
    const size_t count = max_views > 0 ? std::min<size_t>(max_views, n) : n;
    for (size_t k = 0; k < count; ++k) {
      cameras.push_back(views.Camera(pool[k * n / count]));
      names.push_back(views.Name(pool[k * n / count]));
    }
  }
  // The raw model is not moved: the owner's reading renders it from the
  // cameras as they were.
  const std::vector<RenderCamera> raw_cameras = cameras;
  if (!scene_transform.empty()) {
    const SimilarityTransform transform =
        ParseSceneTransform(scene_transform, "--scene_transform");
    for (RenderCamera& camera : cameras) {
      camera = TransformCamera(camera, transform);
    }
  }
  RenderAttack attack;
  if (!image_attack.empty()) {
    const ImageAttackSpec spec = ParseImageAttack(image_attack);
    attack = [spec](const ImageRGB& image) {
      return AttackAsDecoded(spec, image);
    };
  }
  // The frame check and alignment above render as watergs does; the views
  // read below as the named renderer shows them.
  const std::unique_ptr<Rasterizer> reader =
      conventions.IsDefault()
          ? std::unique_ptr<Rasterizer>()
          : WithConventions(MakeCpuRasterizer(), conventions);
  Rasterizer& read_with = reader ? *reader : *rasterizer;
  VerificationThresholds thresholds;
  thresholds.present_p = present_p;
  const Bits* claim = expected.empty() ? nullptr : &expected;
  OwnerExtraction both;
  if (raw_path.empty()) {
    both.blind =
        ExtractWatermark(read_with, ply.model, cameras, names, *decoder, claim,
                         ParseBackground(background), thresholds, attack);
  } else {
    both = ExtractWatermarkWithReference(
        read_with, ply.model, raw.model, cameras, names, *decoder, claim,
        ParseBackground(background), thresholds, attack, {}, raw_cameras);
  }
  const ExtractionResult& r = both.blind;

  std::printf(
      "extract: %zu views of %s (%zu Gaussians)%s\n", r.views.size(),
      input_path.c_str(), ply.model.size(),
      reader ? (" as " + conventions_name + " renders them").c_str() : "");
  std::printf("extract: recovered message hex %s\n",
              BitsToHex(r.recovered).c_str());
  std::printf("extract: recovered bits        %s\n",
              BitsToString(r.recovered).c_str());
  if (!key.empty()) {
    // What the owner typed, if the model carries this key's watermark.
    std::printf("extract: message under the key hex %s (key SHA-256 %s)\n",
                BitsToHex(ApplyKey(r.recovered, key)).c_str(),
                KeyFingerprint(key).c_str());
  }
  if (!raw_path.empty()) {
    std::printf("extract (owner's reading, minus %s): recovered hex %s\n",
                raw_path.c_str(), BitsToHex(both.owner.recovered).c_str());
  }
  if (r.has_expected) {
    std::printf("extract: expected bits         %s\n",
                BitsToString(r.expected).c_str());
    PrintVerdict(r, "", present_p);
    if (!raw_path.empty()) {
      PrintVerdict(both.owner, " (owner's reading)", present_p);
    }
  }
  if (!json_path.empty()) {
    nlohmann::json j = nlohmann::json::parse(ExtractionToJson(r));
    if (!raw_path.empty()) {
      j["owner"] = nlohmann::json::parse(ExtractionToJson(both.owner));
      j["owner"]["raw_path"] = raw_path;
    }
    j["render_conventions"] = conventions_name;
    j["provenance"] = Provenance(argc, argv);
    AtomicWriteFile(json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(extract,
                "Extracts and verifies a WATER-GS watermark from a 3DGS model",
                watergs::RunExtract);
