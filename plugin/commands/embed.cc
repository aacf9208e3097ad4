// `watergs embed`: fine-tunes a trained 3DGS model (PLY) on its COLMAP
// workspace so that the frozen decoder reads the owner's message from its
// renders (WATER-GS), and writes the watermarked PLY in the input's layout.
#include <omp.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/loss.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "gaussian/util/text_util.h"
#include "plugin/command.h"
#include "plugin/embed_inputs.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/ownership_report.h"
#include "plugin/report_evidence.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/embedder.h"
#include "watermark/evaluation.h"
#include "watermark/extractor.h"
#include "watermark/message.h"

namespace watergs {
namespace {

using Clock = std::chrono::steady_clock;

// The paper's layers at its strengths, reviewed by --distortions auto.
constexpr char kCandidateDistortions[] = "gn:0.01,dropout:0.1,crop:0.1";

// embed's default --target_psnr (dB from the input model's renders).
constexpr double kDefaultTargetPsnr = 38;

struct EmbedArgs {
  std::string input_path, output_path, decoder_path, message, report_path;
  std::string key_option;
  std::string align = "auto";
  WorkspaceOptions workspace;
  // Defaults: the settings measured best on the demo at 2 cores
  // (docs/history.md, "The owner's reading", "The default serves both
  // readers"): whole frames (a crop above 512x512, --crop_size auto), half the
  // iterations from free viewpoints, the owner's reading with a logit margin of
  // 1 plus a half-weight blind term, an MSE term towards the input model's
  // renders and a fifth of Inria's rates (the change stays small: 37 dB from
  // the raw renders on the demo), no density control (the file keeps its size).
  int64_t iterations = 1500;
  double gamma = 0.03, beta = 0.2;
  std::string mask = "ALL";
  std::string distortions = "identity,gn:0.01,dropout:0.1,crop:0.1";
  std::string crop_size = "auto";
  bool full_frame_loss = false;
  double free_view_fraction = 0.5;
  int free_view_neighbors = 0;
  std::string decoder_jitter = "none";
  std::string jpeg_layer = "none";
  double margin = 1;
  std::string fidelity = "input";
  // The reading the message term optimises: blind (the decoder's logits),
  // owner (their difference from the raw model's at the same viewpoint) or
  // both. The default serves both readers from one file: the owner's reading
  // at its fidelity, and a half-weight blind term (sign only) that lets a
  // reader without the raw model find the message over many views
  // (docs/decoder_design.md, "one file for both readers").
  std::string reading = "both";
  double blind_weight = 0.5, blind_margin = 0;
  // > 0: the blind weight steered so the renders sit this far (dB) from the
  // input model's at the check cameras (fidelity_budget.h). 38 by default:
  // one held-out view read blind under 1% on fern and horns (docs/history.md).
  double target_psnr = kDefaultTargetPsnr;
  double mse_weight = 50;
  double masking = 0;
  // Multiplies every optimiser rate: Adam moves each parameter by about its
  // rate per step whatever the loss weights, so the rates, not gamma, set
  // how far a model travels from the input.
  double lr_scale = 0.2;
  int check_free_views = 4;
  int hard_views = 0;
  double hard_view_fraction = 0.5;
  int patience = 0;
  double stop_margin = 0;
  int check_views = 4;
  int64_t check_every = 250;
  // "auto": on with every group trainable, off with a partial mask; off by
  // default: density control grows the file (112k -> 1.1M Gaussians on a
  // 48-view scene) for no gain in the message.
  std::string densify = "off";
  std::string background = "0,0,0";
  int64_t seed = 0;
  int num_threads = 0;
  int64_t checkpoint_every = 0;
  bool resume = false;
  // --split: all, or train (every 8th view held out, so that eval scores
  // unseen views); eval: split == "train".
  std::string split = "all";
  bool eval = false;
};

// "none" or "SHIFT,MIN_SCALE,MAX_SCALE".
DecoderJitterOptions ParseDecoderJitter(const std::string& text) {
  DecoderJitterOptions jitter;
  if (text == "none") return jitter;
  std::vector<double> values;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, ',');) {
    const std::optional<double> v = ParseFiniteDouble(part);
    if (!v) break;
    values.push_back(*v);
  }
  if (values.size() != 3) {
    Fail("--decoder_jitter: '" + Printable(text) +
         "' is not none or SHIFT,MIN_SCALE,MAX_SCALE");
  }
  jitter.max_shift = values[0];
  jitter.min_scale = values[1];
  jitter.max_scale = values[2];
  try {
    CheckDecoderJitter(jitter);
  } catch (const Error& e) {
    Fail(std::string("--decoder_jitter: ") + e.what());
  }
  return jitter;
}

// "none" or "Q:FRACTION" (quality 1-100, fraction of iterations in (0, 1]).
void ParseJpegLayer(const std::string& text, EmbedOptions* options) {
  if (text == "none") return;
  const size_t colon = text.find(':');
  const std::optional<double> quality =
      ParseFiniteDouble(text.substr(0, colon));
  const std::optional<double> fraction =
      colon == std::string::npos ? std::nullopt
                                 : ParseFiniteDouble(text.substr(colon + 1));
  if (!quality || !fraction || *quality != std::floor(*quality) ||
      *quality < 1 || *quality > 100 || !(*fraction > 0 && *fraction <= 1)) {
    Fail("--jpeg_layer: '" + Printable(text) +
         "' is not none or QUALITY:FRACTION (quality 1-100, fraction in "
         "(0, 1])");
  }
  options->jpeg_quality = int(*quality);
  options->jpeg_fraction = *fraction;
}

// "auto" (-1), or the crop's side in whole pixels (0: whole frames).
int ParseCropSize(const std::string& text) {
  if (text == "auto") return -1;
  int side = -1;
  const char* end = text.data() + text.size();
  const auto [stop, error] = std::from_chars(text.data(), end, side);
  if (text.empty() || error != std::errc() || stop != end || side < 0 ||
      side > 100000) {
    Fail("--crop_size: '" + Printable(text) +
         "' is not auto or a side in pixels, 0..100000 (0 = whole frames)");
  }
  return side;
}

// "crop 256", "whole frames", "crop 384 (auto: frames above 512x512)".
std::string CropSummary(const std::string& text, int side) {
  std::string what = side > 0 ? "crop " + std::to_string(side) : "whole frames";
  if (text != "auto") return what;
  return what + (side > 0 ? " (auto: frames above 512x512)"
                          : " (auto: frames up to 512x512)");
}

// The crop side for `text` on these views: auto looks at the largest frame.
int ResolveCropSize(const std::string& text, const TrainingViews& views,
                    const std::vector<size_t>& train_views) {
  const int side = ParseCropSize(text);
  if (side >= 0) return side;
  int64_t largest = 0;
  for (size_t v : train_views) {
    const RenderCamera camera = views.Camera(v);
    largest = std::max<int64_t>(largest, int64_t(camera.width) * camera.height);
  }
  return AutoCropSize(largest);
}

void Validate(const EmbedArgs& a) {
  if (SamePath(a.input_path, a.output_path)) {
    Fail("embed: --output_path must differ from --input_path");
  }
  if (a.iterations < 1) Fail("--iterations must be at least 1");
  if (!(a.gamma >= 0)) Fail("--gamma must be >= 0");
  if (!(a.beta >= 0 && a.beta <= 1)) Fail("--beta must be in [0, 1]");
  ParseCropSize(a.crop_size);
  if (!(a.stop_margin >= 0)) Fail("--stop_margin must be >= 0");
  if (a.patience < 0 || a.check_views < 0 || a.check_every < 1) {
    Fail("--patience, --check_views must be >= 0, --check_every >= 1");
  }
  if (a.densify != "on" && a.densify != "off" && a.densify != "auto") {
    Fail("--densify: on, off or auto");
  }
  if (!(a.lr_scale > 0 && a.lr_scale <= 100)) {
    Fail("--lr_scale must be in (0, 100]");
  }
  if (a.hard_views < 0) Fail("--hard_views must be >= 0");
  if (a.hard_views > 0 && a.free_view_fraction <= 0) {
    Fail(
        "--hard_views replays free-view iterations: give "
        "--free_view_fraction > 0");
  }
  if (!(a.hard_view_fraction >= 0 && a.hard_view_fraction <= 1))
    Fail("--hard_view_fraction must be in [0, 1]");
  if (!(a.free_view_fraction >= 0 && a.free_view_fraction <= 1))
    Fail("--free_view_fraction must be in [0, 1]");
  if (a.checkpoint_every < 0) Fail("--checkpoint_every must be >= 0");
  CheckOutputFile(a.output_path);  // before the fine-tuning, not after
  if (!a.report_path.empty()) {
    for (const std::string& path :
         {a.input_path, a.output_path, a.decoder_path}) {
      if (SamePath(path, a.report_path)) {
        Fail("embed: --report " + a.report_path +
             " is one of the inputs or outputs");
      }
    }
    CheckOutputFile(a.report_path);
  }
}

// The ownership report of the written model on all of the workspace's
// cameras, with eval's default attacks; `watergs report` on the files
// writes the same page.
void WriteEmbedReport(const EmbedArgs& a, int argc, char** argv,
                      Rasterizer& rasterizer, const GaussianModel& raw,
                      const GaussianModel& watermarked,
                      const TrainingViews& views, BitDecoder& decoder,
                      const Bits& message,
                      const std::array<float, 3>& background,
                      const ModelPlacement& placement) {
  EvaluationOptions options;
  options.background = background;
  ScaleToModelUnits(placement, &options.model_attacks);
  options.show_progress = true;
  options.lpips_note = "not computed (embed --report)";
  options.ground_truth = true;
  std::vector<size_t> all(views.NumViews());
  for (size_t k = 0; k < all.size(); ++k) all[k] = k;
  ReportRequest request;
  request.owner_reading = a.reading != "blind";
  request.raw_path = a.input_path;
  request.watermarked_path = a.output_path;
  request.decoder_path = a.decoder_path;
  request.message_text = a.message;
  request.key_option = a.key_option;
  request.workspace = a.workspace;
  request.background = a.background;
  request.generator = VersionLine();
  request.commands.push_back(
      {"The embedding, as run", CommandLine(argc, argv)});
  std::string report_command =
      "watergs report --raw_path " + ShellQuote(a.input_path) +
      " --input_path " + ShellQuote(a.output_path) + " --workspace_path " +
      ShellQuote(a.workspace.workspace_path);
  if (!a.workspace.input_path.empty()) {
    report_command += " --sparse_path " + ShellQuote(a.workspace.input_path);
  }
  if (!a.workspace.image_path.empty()) {
    report_command += " --image_path " + ShellQuote(a.workspace.image_path);
  }
  if (a.workspace.downscale != 1) {
    report_command += " --downscale " + std::to_string(a.workspace.downscale);
  }
  if (a.reading == "blind") report_command += " --reading blind";
  if (a.align != "auto") report_command += " --align " + ShellQuote(a.align);
  report_command += " --decoder " + ShellQuote(a.decoder_path) +
                    ClaimOptions(a.message, a.key_option) + " --output_path " +
                    ShellQuote(a.report_path);
  if (a.background != "0,0,0") {
    report_command += " --background " + ShellQuote(a.background);
  }
  request.commands.push_back(
      {"This report, from the files (every figure in it)", report_command});
  EvaluationReport evaluation = EvaluateWatermark(
      rasterizer, raw, watermarked, views, all, decoder, message, options);
  const std::string html = OwnershipReportToHtml(CollectOwnershipReport(
      rasterizer, raw, watermarked, {}, views, all, views.NumViews(), decoder,
      message, options, std::move(evaluation), request));
  AtomicWriteFile(a.report_path, html);
  std::printf("embed: wrote %s (%zu kB)\n", a.report_path.c_str(),
              html.size() / 1000);
}

// Seconds of one forward + backward pass of the rasterizer at `rect`
// (empty = whole frame), median of `repeats`.
double RasterSeconds(Rasterizer& rasterizer, const GaussianModel& model,
                     const RenderCamera& camera, const PixelRect& rect,
                     int repeats) {
  std::vector<double> times;
  RenderOptions options;
  options.rect = rect;
  ImageRGB image;
  GaussianGradients grads;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = Clock::now();
    std::unique_ptr<RenderContext> context;
    rasterizer.Forward(model, camera, options, &image, &context);
    ImageRGB grad(image.width, image.height);
    std::fill(grad.data.begin(), grad.data.end(), 1e-3f);
    rasterizer.Backward(model, *context, grad, &grads);
    times.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

void PrintTimings(const Embedder& embedder) {
  const EmbedTimings& t = embedder.total_timings();
  const double n = std::max<int64_t>(1, embedder.iteration());
  std::printf(
      "embed: per iteration %.1f ms = distortion %.1f + render %.1f + image "
      "loss %.1f + decoder %.1f + backward %.1f + density %.1f + adam %.1f\n",
      1e3 * t.Total() / n, 1e3 * t.distortion / n, 1e3 * t.render / n,
      1e3 * t.image_loss / n, 1e3 * t.decoder / n, 1e3 * t.backward / n,
      1e3 * t.density / n, 1e3 * t.adam / n);
  if (embedder.num_checks() > 0) {
    std::printf("embed: checks %.1f s, %lld of %.1f s each (--check_every)\n",
                embedder.check_seconds(),
                static_cast<long long>(embedder.num_checks()),
                embedder.check_seconds() / embedder.num_checks());
  }
}

int RunEmbed(int argc, char** argv) {
  EmbedArgs a;
  OptionParser parser("embed",
                      "Embeds a WATER-GS watermark into a trained 3DGS model "
                      "by fine-tuning it against a frozen decoder.");
  parser.AddRequired(
      "input_path", &a.input_path,
      "Trained 3DGS model (PLY, compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("workspace_path", &a.workspace.workspace_path,
                     "COLMAP workspace the model was trained on");
  parser.Add("sparse_path", &a.workspace.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("image_path", &a.workspace.image_path,
             "Image folder (default <workspace>/images)");
  parser.Add("downscale", &a.workspace.downscale, "Image downscale: 1,2,4,8");
  parser.Add("align", &a.align, kAlignHelp);
  a.decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &a.decoder_path, kDecoderHelp);
  parser.AddRequired("message", &a.message,
                     std::string("Message: ") + kMessageFormats);
  parser.Add("key", &a.key_option, kKeyHelp);
  parser.AddRequired("output_path", &a.output_path, "Watermarked PLY");
  parser.Add("iterations", &a.iterations, "Fine-tuning iterations");
  parser.Add("gamma", &a.gamma, "Weight of the message loss");
  parser.Add("beta", &a.beta, "Weight of D-SSIM in the image loss");
  parser.Add("mask", &a.mask,
             "ALL or trainable groups: xyz,f_dc,f_rest,opacity,scaling,"
             "rotation (a partial mask needs density control off)");
  parser.Add("distortions", &a.distortions,
             "3D distortion layers sampled per iteration, or none, or auto "
             "(chosen per scene: each of " +
                 std::string(kCandidateDistortions) +
                 " is simulated once two checks in a row find that it breaks "
                 "more than 1% of the bits the plain render reads), or "
                 "auto:LIST (those candidates)");
  parser.Add("crop_size", &a.crop_size,
             "Side of the random crop rendered per iteration, 0 = whole "
             "frames, or auto: whole frames of up to 262,144 pixels "
             "(512x512), a " +
                 std::to_string(kAutoCropSide) +
                 " crop above (the time per iteration stops growing with the "
                 "frame)");
  parser.AddFlag("full_frame_loss", &a.full_frame_loss,
                 "Render whole frames for the image loss (decoder on crop)");
  parser.Add("free_view_fraction", &a.free_view_fraction,
             "Fraction of iterations rendered between two training cameras, "
             "with the input model's render as the image target (the message "
             "then holds in novel views)");
  parser.Add("free_view_neighbors", &a.free_view_neighbors,
             "Free viewpoints lie between a camera and one of its this many "
             "nearest training cameras (0 = any training camera)");
  parser.Add("decoder_jitter", &a.decoder_jitter,
             "SHIFT,MIN_SCALE,MAX_SCALE: the decoder reads each render "
             "shifted by up to SHIFT pixels and resized by a factor in "
             "[MIN_SCALE, MAX_SCALE], or none");
  parser.Add("jpeg_layer", &a.jpeg_layer,
             "QUALITY:FRACTION: on that fraction of the iterations the "
             "decoder reads the render through a real JPEG round trip at "
             "QUALITY (gradient straight through), for leaks saved as JPEG "
             "screenshots; or none");
  parser.Add("margin", &a.margin,
             "Push every logit at least this far past 0 (0 = plain BCE)");
  parser.Add("fidelity", &a.fidelity,
             "Image target on training cameras: photos, or input (the input "
             "model's render: changes go to the message only)");
  parser.Add("reading", &a.reading,
             "The reading the embedding optimises: blind (the decoder's "
             "logits, what extract reads alone) or owner (logits minus the "
             "raw model's at the same viewpoint, what extract --raw_path "
             "reads), or both (the default: the owner's, plus a blind term: "
             "--blind_weight, --blind_margin). blind also sets the blind "
             "defaults of --margin 3, --fidelity photos, --mse_weight 0, "
             "--lr_scale 1 (unless given)");
  parser.Add("blind_weight", &a.blind_weight,
             "--reading both: weight of the blind term beside the owner's");
  parser.Add("blind_margin", &a.blind_margin,
             "--reading both: the margin the blind term pushes the logits "
             "past (0: their sign; a reader aggregating views needs little)");
  parser.Add("target_psnr", &a.target_psnr,
             "--reading both: > 0 raises --blind_weight at every check (x2 "
             "at most, back down to it at least) while the renders sit "
             "above this many dB from the input model's at the check views "
             "and free viewpoints: a scene whose message costs little spends "
             "the headroom on the blind reading; 0: the weight stays as "
             "given (also when --blind_weight is 0 or --check_views 0 and "
             "no target is given)");
  parser.Add("mse_weight", &a.mse_weight,
             "> 0: image loss = this x MSE (PSNR's measure) instead of L1 + "
             "D-SSIM");
  parser.Add("masking", &a.masking,
             "> 0 (with --mse_weight): texture masking, each pixel's squared "
             "error weighted by 1 / (1 + sigma / this), sigma the local "
             "luminance deviation; changes cost less where the image is "
             "textured (measured: docs/history.md)");
  parser.Add("lr_scale", &a.lr_scale,
             "Multiply every optimiser rate by this (Adam moves each parameter "
             "by about its rate a step, whatever the loss weights)");
  parser.Add("hard_views", &a.hard_views,
             "> 0: a pool of this many free viewpoints that "
             "--hard_view_fraction of the free-view iterations revisit, each "
             "as often as it still falls short of reading every bit past "
             "the margin (scored at each check)");
  parser.Add("hard_view_fraction", &a.hard_view_fraction,
             "Share of the free-view iterations drawn from the --hard_views "
             "pool");
  parser.Add("check_free_views", &a.check_free_views,
             "Free viewpoints decoded at each check too (early stopping "
             "waits for them)");
  parser.Add("patience", &a.patience,
             "Stop after this many checks at BER 0 (0 = never)");
  parser.Add("stop_margin", &a.stop_margin,
             "> 0: stop at the first check where every bit of every check "
             "view and free viewpoint reads at least this far past zero "
             "(the strength the scene calls for; 0 = run every iteration)");
  parser.Add("check_views", &a.check_views, "Views decoded at each check");
  parser.Add("check_every", &a.check_every, "Iterations between checks");
  parser.Add("densify", &a.densify,
             "Adaptive density control: on, off or auto (on with --mask "
             "ALL, off with a partial mask)");
  parser.Add("background", &a.background, "r,g,b, black or white");
  parser.Add("seed", &a.seed, "Random seed");
  parser.Add("num_threads", &a.num_threads, "Threads (0 = all cores)");
  parser.Add("checkpoint_every", &a.checkpoint_every,
             "Write OUTPUT.ckpt every N iterations (0 = never)");
  parser.AddFlag("resume", &a.resume, "Continue from OUTPUT.ckpt");
  parser.Add("report", &a.report_path,
             "Also write the ownership report (HTML, see watergs report) of "
             "the written model on all cameras to this file");
  parser.Add("split", &a.split,
             "Views to fine-tune on: all, or train (all but the held-out "
             "views: the workspace's test_views.txt, else every 8th, as "
             "train --split train holds out, so that eval scores unseen "
             "views)");
  parser.AddAlias("eval", "split", "train");
  if (!parser.Parse(argc, argv)) return 0;
  if (a.split != "all" && a.split != "train") {
    Fail("embed: --split all or train, not '" + a.split + "'");
  }
  a.eval = a.split == "train";
  if (a.reading == "blind") {
    // The blind reading's own defaults (docs/history.md, "One view is
    // enough"): it must overcome the scene's lean per bit, so a wider margin,
    // L1 + D-SSIM to the photos and Inria's rates; options given win.
    if (!parser.Given("margin")) a.margin = 3;
    if (!parser.Given("fidelity")) a.fidelity = "photos";
    if (!parser.Given("mse_weight")) a.mse_weight = 0;
    if (!parser.Given("lr_scale")) a.lr_scale = 1;
  }
  Validate(a);
  if (a.num_threads > 0) omp_set_num_threads(a.num_threads);
  const std::string checkpoint_path = a.output_path + ".ckpt";
  if (a.resume && !std::filesystem::exists(checkpoint_path)) {
    FailAt(checkpoint_path, "no checkpoint to resume (use --checkpoint_every)");
  }

  EmbedOptions options = DefaultEmbedOptions(a.iterations);
  options.gamma = a.gamma;
  options.beta = a.beta;
  ScaleRates(a.lr_scale, &options.adam);
  options.trainable = ParseParamMask(a.mask);
  if (a.distortions == "auto" || a.distortions.rfind("auto:", 0) == 0) {
    if (a.check_views < 1) {
      Fail(
          "--distortions auto reviews the layers on the check views: give "
          "--check_views >= 1");
    }
    options.choose_distortions = true;
    options.distortions =
        ParseDistortionList(a.distortions == "auto" ? kCandidateDistortions
                                                    : a.distortions.substr(5));
  } else if (a.distortions != "none") {
    options.distortions = ParseDistortionList(a.distortions);
  }
  options.full_frame_image_loss = a.full_frame_loss;
  options.free_view_fraction = a.free_view_fraction;
  options.free_view_neighbors = a.free_view_neighbors;
  options.hard_views = a.hard_views;
  options.hard_view_fraction = a.hard_view_fraction;
  options.decoder_jitter = ParseDecoderJitter(a.decoder_jitter);
  ParseJpegLayer(a.jpeg_layer, &options);
  options.margin = a.margin;
  if (a.fidelity != "photos" && a.fidelity != "input") {
    Fail("--fidelity: photos or input");
  }
  options.fidelity_to_input = a.fidelity == "input";
  if (a.reading != "blind" && a.reading != "owner" && a.reading != "both") {
    Fail("--reading: blind, owner or both");
  }
  options.owner_reading = a.reading != "blind";
  if (a.reading == "both") {
    options.blind.weight = a.blind_weight;
    options.blind.margin = a.blind_margin;
    // The default target needs a blind term to steer and checks to steer
    // it at; without either the run keeps its fixed weight (weight 0 is the
    // owner's run exactly). A target the user gives is held to both.
    const bool default_target = !parser.Given("target_psnr");
    options.budget.target_db =
        default_target && (a.blind_weight == 0 || a.check_views < 1)
            ? 0
            : a.target_psnr;
    try {
      CheckFidelityBudget(options.budget);
    } catch (const std::invalid_argument& e) {
      Fail(std::string("--") + e.what());
    }
    if (options.budget.enabled()) {
      if (a.check_views < 1) {
        Fail(
            "--target_psnr steers the blind weight at the checks: give "
            "--check_views >= 1");
      }
      if (!(a.blind_weight > 0 &&
            a.blind_weight <= options.budget.max_weight)) {
        Fail(std::string(default_target ? "--target_psnr (on by default)"
                                        : "--target_psnr") +
             " raises --blind_weight from its value, which must be > 0 and "
             "<= " +
             std::to_string(static_cast<int>(options.budget.max_weight)) +
             " (--target_psnr 0: a fixed weight)");
      }
      // The given weight is the floor: the target spends headroom, it never
      // weakens the blind reading the user asked for.
      options.budget.min_weight = a.blind_weight;
    }
  } else if (parser.Given("blind_weight") || parser.Given("blind_margin") ||
             parser.Given("target_psnr")) {
    Fail(
        "--blind_weight, --blind_margin and --target_psnr go with --reading "
        "both");
  }
  options.mse_weight = a.mse_weight;
  options.masking = a.masking;
  options.patience = a.patience;
  options.stop_margin = a.stop_margin;
  options.check_every = a.check_every;
  const bool all_trainable =
      std::all_of(options.trainable.begin(), options.trainable.end(),
                  [](bool t) { return t; });
  options.densify = a.densify == "auto" ? all_trainable : a.densify == "on";
  // Checked here too so that the refusal comes before the workspace loads.
  if (options.densify && !all_trainable) {
    Fail(
        "--densify on needs --mask ALL: density control changes every "
        "parameter group, which a partial mask keeps bit-identical");
  }
  options.background = ParseBackground(a.background);
  options.seed = static_cast<uint64_t>(a.seed);
  options.checkpoint_path = checkpoint_path;
  options.checkpoint_every = a.checkpoint_every;
  options.show_progress = true;

  const std::string key = ResolveKey(a.key_option);
  EmbedInputs in = LoadEmbedInputs(a.input_path, a.decoder_path, a.message, key,
                                   a.workspace, parser.device(), a.eval);
  PlyData& ply = in.ply;
  // Before anything else is said: a model of another scene is one line.
  const PlacedViews placed = PlaceByOption(
      "embed", a.align, *MakeRasterizer(parser.device()), ply.model,
      a.input_path, *in.workspace, *in.views, options.background);
  PrintKeyNotice("embed", key);
  // The model's frame sets its units: the noise layer's sigma and the
  // scene extent (Inria's position rates) are in scene units.
  const double model_units = placed.placement.workspace_to_model.scale;
  ScaleToModelUnits(placed.placement, &options.distortions);
  const BitDecoder* decoder = in.decoder.get();
  const Bits& message = in.message;
  const TrainingViews& views = placed.views();
  const std::vector<size_t>& train_views = in.train_views;
  options.check_views = SpreadViews(train_views, a.check_views);
  // Between two training cameras, as extract --num_views samples them; a
  // seed of its own, so they are not the free-view iterations' cameras.
  options.check_free_views = SampleViewpointsBetween(
      views, train_views, std::max(a.check_free_views, 0),
      uint64_t(a.seed) + 7919);
  const double extent = in.workspace->SceneExtent() * model_units;
  const RenderCamera first = views.Camera(train_views.front());
  options.crop_size = ResolveCropSize(a.crop_size, views, train_views);
  std::printf(
      "embed: %zu Gaussians, %zu views %dx%d, %d-bit message %s, "
      "distortions %s, %s, density control %s, %d threads, device %s\n",
      ply.model.size(), train_views.size(), first.width, first.height,
      decoder->NumBits(), BitsToHex(message).c_str(), a.distortions.c_str(),
      CropSummary(a.crop_size, options.crop_size).c_str(),
      options.densify ? "on" : "off", omp_get_max_threads(),
      DeviceName(parser.device()).c_str());

  const GaussianModel raw = ply.model;
  Embedder embedder(options, views, train_views, std::move(ply.model), extent,
                    in.decoder.get(), message, MakeRasterizer(parser.device()));
  if (embedder.device_resident()) {
    std::printf(
        "embed: every step on the GPU (model, moments and decoder "
        "resident)\n");
  } else if (!embedder.host_step_reason().empty()) {
    std::printf(
        "embed: steps on the host, renders and decoder on the GPU (%s)\n",
        embedder.host_step_reason().c_str());
  }
  if (a.resume) {
    embedder.Resume(checkpoint_path);
    std::printf("embed: resumed at iteration %lld\n",
                static_cast<long long>(embedder.iteration()));
  }
  const CheckResult before = embedder.Check(options.check_views);
  const auto t0 = Clock::now();
  const bool early = embedder.Run();
  const double seconds =
      std::chrono::duration<double>(Clock::now() - t0).count();
  if (a.checkpoint_every > 0) embedder.SaveCheckpoint(checkpoint_path);
  const CheckResult after = embedder.Check(options.check_views);

  ply.layout.RemapExtras(embedder.origin());
  WritePly(a.output_path, embedder.model(), ply.layout);

  // Fidelity: watermarked vs raw renders on the check views.
  const double psnr_vs_raw =
      MeasureFidelity(embedder.rasterizer(), raw, embedder.model(), views,
                      options.check_views, options.background)
          .psnr_vs_raw;
  // The run stopped at the check that met --stop_margin, else at
  // --patience checks at BER 0.
  const bool read_past_margin =
      options.stop_margin > 0 && after.weakest_margin >= options.stop_margin;
  std::printf("embed: %lld iterations in %s%s, %zu Gaussians\n",
              static_cast<long long>(embedder.iteration()),
              FormatDuration(seconds).c_str(),
              !early ? ""
              : read_past_margin
                  ? " (stopped: every check view and free viewpoint read past "
                    "--stop_margin)"
                  : " (stopped early: check BER 0)",
              embedder.model().size());
  std::printf(
      "embed: check views (%zu): BER %.2f%% -> %.2f%% (mean of views), "
      "%.2f%% (mean logits); PSNR vs ground truth %.2f -> %.2f dB, "
      "vs raw %.2f dB\n",
      options.check_views.size(), 100 * before.mean_ber, 100 * after.mean_ber,
      100 * after.aggregate_ber, before.psnr, after.psnr, psnr_vs_raw);
  if (options.budget.enabled()) {
    std::printf(
        "embed: blind weight %.3g -> %.3g after the last check (--target_psnr "
        "%.2f dB; the renders now read %.2f dB from the input's at %zu check "
        "views and %zu free viewpoints)\n",
        options.blind.weight, embedder.blind_weight(), options.budget.target_db,
        after.psnr_vs_input, options.check_views.size(),
        options.check_free_views.size());
  }
  if (const DistortionChoice* choice = embedder.distortion_choice()) {
    std::printf("embed: distortion layers %s\n",
                choice->Summary(embedder.iteration()).c_str());
  }
  PrintTimings(embedder);
  if (options.crop_size > 0 && !a.full_frame_loss) {
    auto rasterizer = MakeRasterizer(parser.device());
    const int w = std::min(options.crop_size, first.width);
    const int h = std::min(options.crop_size, first.height);
    const PixelRect rect{(first.width - w) / 2, (first.height - h) / 2, w, h};
    const double crop_s =
        RasterSeconds(*rasterizer, embedder.model(), first, rect, 3);
    const double frame_s =
        RasterSeconds(*rasterizer, embedder.model(), first, PixelRect{}, 3);
    std::printf(
        "embed: render+backward %dx%d crop %.1f ms vs whole %dx%d frame "
        "%.1f ms: %.1fx faster\n",
        w, h, 1e3 * crop_s, first.width, first.height, 1e3 * frame_s,
        frame_s / crop_s);
  }
  std::printf("embed: wrote %s\n", a.output_path.c_str());
  if (!a.report_path.empty()) {
    WriteEmbedReport(a, argc, argv, embedder.rasterizer(), raw,
                     embedder.model(), views, *in.decoder, message,
                     options.background, placed.placement);
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(embed, "Embeds a WATER-GS watermark into a 3DGS model",
                watergs::RunEmbed);
