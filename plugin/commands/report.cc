// `watergs report`: the ownership report an owner hands over, as one
// self-contained HTML file (plugin/ownership_report.h): renders the raw and
// the watermarked model from the workspace's cameras, reads the watermark
// (the claim, the raw model as the control, the watermarked model under
// attacks, suspect copies) and writes the page atomically.
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/text_util.h"
#include "plugin/command.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/ownership_report.h"
#include "plugin/report_evidence.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/evaluation.h"
#include "watermark/message.h"

namespace watergs {
namespace {

int RunReport(int argc, char** argv) {
  const auto begin = std::chrono::steady_clock::now();
  ReportRequest request;
  std::string output_path, copies;
  std::string model_attacks = kDefaultModelAttacks;
  std::string image_attacks = kDefaultImageAttacks;
  std::string lpips_path;
  int max_views = 0, num_threads = 0;
  int64_t seed = 0;
  double present_p = VerificationThresholds().present_p;
  OptionParser parser(
      "report",
      "Writes an ownership report: one self-contained HTML file (images "
      "embedded, no network, no script) with the claim (message, decoder "
      "checksum, p-value, verdict, false-positive rate), per view the raw "
      "and watermarked renders and their difference x10, BER per view as a "
      "chart, PSNR/SSIM, the attacks tried with their BER and verdicts, and "
      "the commands that reproduce it. Reads the workspace's cameras as "
      "extract does (all, or --max_views spread evenly).");
  parser.AddRequired("raw_path", &request.raw_path,
                     "The raw (unwatermarked) model");
  parser.AddRequired("input_path", &request.watermarked_path,
                     "The watermarked model the claim is about (PLY, "
                     "compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("workspace_path", &request.workspace.workspace_path,
                     "COLMAP workspace whose cameras are rendered (its "
                     "images, if any, give PSNR/SSIM against ground truth)");
  parser.Add("sparse_path", &request.workspace.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("image_path", &request.workspace.image_path,
             "Image folder (default <workspace>/images)");
  parser.Add("downscale", &request.workspace.downscale,
             "Image downscale: 1,2,4,8");
  std::string align = "auto";
  parser.Add("align", &align, kAlignHelp);
  request.decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &request.decoder_path, kDecoderHelp);
  parser.AddRequired("message", &request.message_text,
                     std::string("Claimed message: ") + kMessageFormats);
  parser.Add("key", &request.key_option, kKeyHelp);
  parser.AddRequired("output_path", &output_path, "The HTML file to write");
  parser.Add("copies", &copies,
             "Suspect copies (e.g. files from watergs attack), "
             "comma-separated PLYs read on the same cameras");
  parser.Add("attacks", &model_attacks,
             "Model attacks on the watermarked PLY, each alone (see watergs "
             "attack; identity, the claim, is always read)");
  parser.Add("image_attacks", &image_attacks,
             "Attacks on renders: jpeg:Q, resize:F, crop:F ('' for none)");
  parser.Add("max_views", &max_views,
             "Use at most this many cameras, spread evenly (0 = all)");
  parser.Add("show_views", &request.show_views,
             "Views shown in full (raw, watermarked, difference)");
  parser.Add("lpips_weights", &lpips_path,
             "LPIPS-VGG weights for an LPIPS column ('' = none)");
  parser.Add("false_positive_rate", &present_p,
             "p-value at or below which the watermark is declared present");
  parser.Add("background", &request.background, "r,g,b, black or white");
  parser.Add("seed", &seed, "Seed of the random attacks");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  std::string reading = "owner";
  parser.Add("reading", &reading,
             "How the claim is read: owner (each view minus the raw model's "
             "render, what embed optimises by default) or blind (the "
             "decoder alone, for a model embedded with --reading blind)");
  if (!parser.Parse(argc, argv)) return 0;
  if (reading != "owner" && reading != "blind") {
    Fail("report: --reading owner or blind");
  }
  request.owner_reading = reading == "owner";
  if (max_views < 0) Fail("report: --max_views must be >= 0");
  if (request.show_views < 0) Fail("report: --show_views must be >= 0");
  if (!(present_p > 0 && present_p < 0.01)) {
    Fail("report: --false_positive_rate must be in (0, 0.01)");
  }
  request.suspect_paths = SplitList(copies);
  std::vector<std::string> inputs = {request.raw_path, request.watermarked_path,
                                     request.decoder_path};
  inputs.insert(inputs.end(), request.suspect_paths.begin(),
                request.suspect_paths.end());
  for (const std::string& input : inputs) {
    if (SamePath(input, output_path)) {
      Fail("report: --output_path " + output_path + " is one of the inputs");
    }
  }
  if (num_threads > 0) omp_set_num_threads(num_threads);
  CheckOutputFile(output_path);  // before the work, not after

  EvaluationOptions options;
  options.model_attacks = model_attacks.empty()
                              ? std::vector<ModelAttackSpec>{}
                              : ParseModelAttackList(model_attacks);
  // The claim is the identity row: read first even if not asked for.
  bool has_identity = false;
  for (const ModelAttackSpec& spec : options.model_attacks) {
    has_identity = has_identity || ToString(spec) == "identity";
  }
  if (!has_identity) {
    options.model_attacks.insert(options.model_attacks.begin(),
                                 ParseModelAttackList("identity").front());
  }
  options.image_attacks = image_attacks.empty()
                              ? std::vector<ImageAttackSpec>{}
                              : ParseImageAttackList(image_attacks);
  options.background = ParseBackground(request.background);
  options.thresholds.present_p = present_p;
  options.seed = uint64_t(seed);
  options.show_progress = true;
  options.lpips_note = "not computed (--lpips_weights not given)";

  // Every input read before the work: a bad one fails at once.
  const ModelData raw = ReadModelFile(request.raw_path);
  const ModelData watermarked = ReadModelFile(request.watermarked_path);
  std::vector<GaussianModel> suspects;
  for (const std::string& path : request.suspect_paths) {
    suspects.push_back(ReadModelFile(path).model);
  }
  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(request.decoder_path, parser.device());
  const Bits bits =
      ApplyKey(ParseMessage(request.message_text, decoder->NumBits()),
               ResolveKey(request.key_option));
  std::unique_ptr<Lpips> lpips;
  if (!lpips_path.empty()) {
    lpips = Lpips::Load(lpips_path);
    options.lpips = lpips.get();
  }
  WorkspaceOptions workspace_options = request.workspace;
  workspace_options.images_optional = true;
  const Workspace workspace = Workspace::Open(workspace_options);
  options.ground_truth = workspace.has_images();
  if (!options.ground_truth) {
    options.ground_truth_note = "none (no image folder at " +
                                workspace.options().image_path +
                                "): only the raw renders are compared";
  }
  const WorkspaceViews workspace_views(workspace);
  auto rasterizer = MakeRasterizer(parser.device());
  // Every model in the raw model's frame: it is the one placed.
  const PlacedViews placed =
      PlaceByOption("report", align, *rasterizer, raw.model, request.raw_path,
                    workspace, workspace_views, options.background);
  const TrainingViews& views = placed.views();
  ScaleToModelUnits(placed.placement, &options.model_attacks);
  const size_t n = views.NumViews();
  const size_t count =
      max_views > 0 ? std::min<size_t>(size_t(max_views), n) : n;
  std::vector<size_t> eval_views;
  for (size_t k = 0; k < count; ++k) eval_views.push_back(k * n / count);

  request.generator = VersionLine();
  request.commands.push_back(
      {"This report (every figure in it)", CommandLine(argc, argv)});
  EvaluationReport evaluation =
      EvaluateWatermark(*rasterizer, raw.model, watermarked.model, views,
                        eval_views, *decoder, bits, options);
  const OwnershipReport report = CollectOwnershipReport(
      *rasterizer, raw.model, watermarked.model, suspects, views, eval_views, n,
      *decoder, bits, options, std::move(evaluation), request);
  const std::string html = OwnershipReportToHtml(report);
  AtomicWriteFile(output_path, html);

  const ExtractionResult& c = report.claim;
  std::printf(
      "report: %zu views; claim (read %s): BER %.2f%% (%d of %zu bits), "
      "p-value %.3g, verdict: %s (false-positive rate %.0e)\n",
      eval_views.size(), request.owner_reading ? "as the owner" : "blind",
      100 * c.ber, c.bit_errors, c.recovered.size(), c.p_value,
      ToString(c.verdict).c_str(), present_p);
  std::printf("report: control (raw model): BER %.2f%%, verdict: %s\n",
              100 * report.raw.ber, ToString(report.raw.verdict).c_str());
  for (const RobustnessRow& row : report.evaluation.robustness) {
    if (row.model != "file") continue;
    const ExtractionResult& e =
        request.owner_reading ? row.owner : row.extraction;
    std::printf("report: copy %s: BER %.2f%%, p-value %.3g, verdict: %s\n",
                row.attack.c_str(), 100 * e.ber, e.p_value,
                ToString(e.verdict).c_str());
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin)
          .count();
  std::printf("report: wrote %s (%.0f kB) in %.1f s\n", output_path.c_str(),
              html.size() / 1e3, seconds);
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(report,
                "Writes an ownership report: one self-contained HTML file "
                "with the claim, renders, BER chart and attacks",
                watergs::RunReport);
