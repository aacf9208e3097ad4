// `watergs eval`: image quality and watermark robustness of a watermarked
// 3DGS model against its raw original on a workspace's held-out views, as
// JSON and a Markdown table (docs/evaluation.md).
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
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

// The views to evaluate: held-out (every 8th), all, or at most `max_views`
// of those spread evenly.
std::vector<size_t> SelectViews(const Workspace& workspace,
                                const std::string& which, int max_views) {
  std::vector<size_t> views;
  if (which == "test") {
    views = workspace.TestViews(true);
  } else if (which == "train") {
    views = workspace.TrainViews(true);
  } else if (which == "all") {
    views = workspace.TestViews(false);
    if (views.empty()) views = workspace.TrainViews(false);
  } else {
    Fail("eval: --split must be test, train or all, not '" + which + "'");
  }
  if (max_views > 0 && size_t(max_views) < views.size()) {
    std::vector<size_t> spread;
    for (int k = 0; k < max_views; ++k) {
      spread.push_back(views[k * views.size() / max_views]);
    }
    views = spread;
  }
  return views;
}

// Loads the LPIPS weights. Weights missing at the default path (relative to
// the current folder) skip LPIPS: `skipped` says why in a line for the user,
// `note` in the report; missing at a path the user gave is an error.
std::unique_ptr<Lpips> LoadLpips(const std::string& path, bool given,
                                 std::string* note, std::string* skipped) {
  if (path.empty()) {
    *note = "not computed (--lpips_weights is empty)";
    return nullptr;
  }
  if (!std::filesystem::exists(path)) {
    const std::string fetch =
        "bash datasets_scripts/download_lpips_weights.sh fetches them";
    if (given) {
      FailAt(path, "LPIPS weights not found (--lpips_weights; " + fetch +
                       ", '' skips LPIPS)");
    }
    const std::string why = "no weights at the default " + path +
                            " (relative to the current folder; " + fetch +
                            ", --lpips_weights names another file)";
    *note = "not computed: " + why;
    *skipped = "eval: LPIPS skipped: " + why;
    return nullptr;
  }
  return Lpips::Load(path);
}

int RunEval(int argc, char** argv) {
  std::string raw_path, input_path, decoder_path, message, output_path;
  std::string key_option;
  std::string report_path;
  std::string model_attacks = kDefaultModelAttacks;
  std::string image_attacks = kDefaultImageAttacks;
  std::string lpips_path = "data/lpips/lpips_vgg.bin";
  std::string which_views = "test", background = "0,0,0";
  WorkspaceOptions workspace_options;
  int max_views = 0, num_threads = 0, attack_draws = 1;
  int64_t seed = 0;
  double present_p = VerificationThresholds().present_p;
  OptionParser parser(
      "eval",
      "Evaluates a watermarked 3DGS model against its raw original on the "
      "workspace's held-out views (every 8th image, as train --split train "
      "holds out): PSNR, "
      "SSIM, MS-SSIM and VGG-LPIPS against ground truth and against the raw "
      "renders; BER, p-value and verdict under each model attack and each "
      "attack on the renders. Prints a Markdown table; --output_path P "
      "writes P.json and P.md.");
  parser.AddRequired("raw_path", &raw_path, "The raw (unwatermarked) model");
  parser.AddRequired(
      "input_path", &input_path,
      "The watermarked model (PLY, compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("workspace_path", &workspace_options.workspace_path,
                     "COLMAP workspace (its images are the ground truth; "
                     "without them only the raw renders are compared)");
  parser.Add("sparse_path", &workspace_options.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("image_path", &workspace_options.image_path,
             "Image folder (default <workspace>/images)");
  parser.Add("downscale", &workspace_options.downscale,
             "Image downscale: 1,2,4,8");
  std::string align = "auto";
  parser.Add("align", &align, kAlignHelp);
  decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &decoder_path, kDecoderHelp);
  parser.AddRequired("message", &message,
                     std::string("Embedded message: ") + kMessageFormats);
  parser.Add("key", &key_option, kKeyHelp);
  parser.Add("output_path", &output_path,
             "Report prefix: writes <prefix>.json and <prefix>.md");
  parser.Add("attacks", &model_attacks,
             "Model attacks, each applied alone (see watergs attack)");
  parser.Add("image_attacks", &image_attacks,
             "Attacks on renders: jpeg:Q, resize:F, crop:F ('' for none)");
  parser.Add("lpips_weights", &lpips_path,
             "LPIPS-VGG weights (datasets_scripts/download_lpips_weights.sh); "
             "'' to skip. The default is relative to the current folder and "
             "LPIPS is skipped (said once) if it is missing there; a path "
             "given that does not exist is an error");
  parser.Add("split", &which_views,
             "Views to evaluate: test (the views train and embed --split "
             "train hold out: test_views.txt, else every 8th), train (the "
             "others) or all");
  parser.AddAlias("views", "split");
  parser.Add("max_views", &max_views,
             "Evaluate at most this many views, spread evenly (0 = all)");
  parser.Add("false_positive_rate", &present_p,
             "p-value at or below which the watermark is declared present");
  parser.Add("background", &background, "r,g,b, black or white");
  parser.Add("seed", &seed, "Seed of the random attacks");
  parser.Add("attack_draws", &attack_draws,
             "Draws of each random 3D attack (gn, dropout, crop); above 1, "
             "a table gives each figure's mean and range over the draws (the "
             "main tables stay the first draw, the paper's protocol)");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  parser.Add("report", &report_path,
             "Also write the ownership report (HTML, see watergs report) of "
             "these views to this file");
  std::string reading = "owner";
  parser.Add("reading", &reading,
             "With --report: how its claim is read, owner (minus the raw "
             "model's renders) or blind (the decoder alone)");
  if (!parser.Parse(argc, argv)) return 0;
  if (reading != "owner" && reading != "blind") {
    Fail("eval: --reading owner or blind");
  }
  if (max_views < 0) Fail("eval: --max_views must be >= 0");
  if (attack_draws < 1 || attack_draws > 1000) {
    Fail("eval: --attack_draws must be in [1, 1000]");
  }
  if (!(present_p > 0 && present_p < 0.01)) {
    Fail("eval: --false_positive_rate must be in (0, 0.01)");
  }
  if (num_threads > 0) omp_set_num_threads(num_threads);
  if (!output_path.empty()) {
    CheckOutputFile(output_path + ".json");  // before the work, not after
    CheckOutputFile(output_path + ".md");
  }
  if (!report_path.empty()) {
    for (const std::string& input : {raw_path, input_path, decoder_path}) {
      if (SamePath(input, report_path)) {
        Fail("eval: --report " + report_path + " is one of the inputs");
      }
    }
    CheckOutputFile(report_path);
  }

  EvaluationOptions options;
  options.model_attacks = model_attacks.empty()
                              ? std::vector<ModelAttackSpec>{}
                              : ParseModelAttackList(model_attacks);
  options.image_attacks = image_attacks.empty()
                              ? std::vector<ImageAttackSpec>{}
                              : ParseImageAttackList(image_attacks);
  options.background = ParseBackground(background);
  options.thresholds.present_p = present_p;
  options.seed = uint64_t(seed);
  options.attack_draws = attack_draws;
  options.show_progress = true;
  const ModelData raw = ReadModelFile(raw_path);
  const ModelData watermarked = ReadModelFile(input_path);
  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(decoder_path, parser.device());
  const Bits bits = ApplyKey(ParseMessage(message, decoder->NumBits()),
                             ResolveKey(key_option));
  // What is left out, said once when every input has been accepted (an
  // error stays the only line).
  std::vector<std::string> notices;
  std::string lpips_skipped;
  std::unique_ptr<Lpips> lpips =
      LoadLpips(lpips_path, parser.Given("lpips_weights"), &options.lpips_note,
                &lpips_skipped);
  if (!lpips_skipped.empty()) notices.push_back(lpips_skipped);
  options.lpips = lpips.get();
  // Without images the renders are still compared with each other and the
  // watermark read; only the comparisons with ground truth are left empty.
  workspace_options.images_optional = true;
  const Workspace workspace = Workspace::Open(workspace_options);
  options.ground_truth = workspace.has_images();
  if (attack_draws > 1 &&
      std::none_of(options.model_attacks.begin(), options.model_attacks.end(),
                   AttackRendersPerDraw)) {
    notices.push_back("eval: --attack_draws " + std::to_string(attack_draws) +
                      ": no attack in --attacks is random (gn, dropout, "
                      "crop): each is read once");
  }
  if (!options.ground_truth) {
    options.ground_truth_note = "none (no image folder at " +
                                workspace.options().image_path +
                                "): only the raw renders are compared";
    notices.push_back("eval: no ground truth: " + options.ground_truth_note);
  }
  const WorkspaceViews workspace_views(workspace);
  const std::vector<size_t> eval_views =
      SelectViews(workspace, which_views, max_views);

  auto rasterizer = MakeRasterizer(parser.device());
  // Both models in the raw model's frame: it is the one placed.
  const PlacedViews placed =
      PlaceByOption("eval", align, *rasterizer, raw.model, raw_path, workspace,
                    workspace_views, options.background);
  const TrainingViews& views = placed.views();
  ScaleToModelUnits(placed.placement, &options.model_attacks);
  for (const std::string& notice : notices) std::cerr << notice << "\n";
  const EvaluationReport report =
      EvaluateWatermark(*rasterizer, raw.model, watermarked.model, views,
                        eval_views, *decoder, bits, options);
  // "1 held-out view", "9 views".
  const std::string views_text = std::to_string(eval_views.size()) +
                                 (which_views == "test" ? " held-out" : "") +
                                 (eval_views.size() == 1 ? " view" : " views");
  std::string markdown =
      "# watergs eval\n\nRaw " + raw_path + " (" +
      std::to_string(report.raw_gaussians) + " Gaussians), watermarked " +
      input_path + " (" + std::to_string(report.watermarked_gaussians) +
      " Gaussians), " + views_text + " of " + workspace_options.workspace_path +
      ".\n\n" + EvaluationToMarkdown(report);
  std::cout << markdown;
  if (!output_path.empty()) {
    AtomicWriteFile(output_path + ".json",
                    WithProvenance(EvaluationToJson(report), 2, argc, argv));
    AtomicWriteFile(output_path + ".md", markdown);
    std::cout << "\neval: wrote " << output_path << ".json and " << output_path
              << ".md\n";
  }
  if (!report_path.empty()) {
    ReportRequest request;
    request.owner_reading = reading == "owner";
    request.raw_path = raw_path;
    request.watermarked_path = input_path;
    request.decoder_path = decoder_path;
    request.message_text = message;
    request.key_option = key_option;
    request.workspace = workspace_options;
    request.background = background;
    request.generator = VersionLine();
    request.commands.push_back(
        {"This evaluation and report (every figure in it)",
         CommandLine(argc, argv)});
    const std::string html = OwnershipReportToHtml(CollectOwnershipReport(
        *rasterizer, raw.model, watermarked.model, {}, views, eval_views,
        views.NumViews(), *decoder, bits, options, report, request));
    AtomicWriteFile(report_path, html);
    std::cout << "eval: wrote " << report_path << " (" << html.size() / 1000
              << " kB)\n";
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(eval,
                "Image quality and watermark robustness of a watermarked "
                "model against its raw original",
                watergs::RunEval);
