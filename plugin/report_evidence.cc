// Gathering an ownership report's evidence (see report_evidence.h).
#include "plugin/report_evidence.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "watermark/message.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

// At most kReportImageWidth wide; area averaging keeps the mean of what it
// shrinks (a difference image keeps its brightness).
ImageRGB Shrink(const ImageRGB& image) {
  if (image.width <= kReportImageWidth) return image;
  const int w = kReportImageWidth;
  const int h =
      std::max(1, int(std::lround(double(image.height) * w / image.width)));
  cv::Mat source(image.height, image.width, CV_32FC3,
                 const_cast<float*>(image.data.data()));
  ImageRGB out(w, h);
  cv::Mat target(h, w, CV_32FC3, out.data.data());
  cv::resize(source, target, target.size(), 0, 0, cv::INTER_AREA);
  return out;
}

ImageRGB AmplifiedDifference(const ImageRGB& a, const ImageRGB& b) {
  ImageRGB out(a.width, a.height);
  for (size_t i = 0; i < out.data.size(); ++i) {
    out.data[i] = std::min(
        1.f, float(kReportDifferenceGain) * std::abs(a.data[i] - b.data[i]));
  }
  return out;
}

// The robustness row of `model` read with `attack`, or null.
const RobustnessRow* FindRow(const EvaluationReport& report,
                             const std::string& model,
                             const std::string& attack) {
  for (const RobustnessRow& row : report.robustness) {
    if (row.model == model && row.attack == attack) return &row;
  }
  return nullptr;
}

}  // namespace

std::optional<std::string> ExtractViewsOption(const std::vector<size_t>& views,
                                              size_t num_views) {
  const size_t m = views.size();
  if (m == 0 || m > num_views) return std::nullopt;
  bool all = m == num_views, spread = true;
  for (size_t k = 0; k < m; ++k) {
    all = all && views[k] == k;
    spread = spread && views[k] == k * num_views / m;
  }
  if (all) return std::string();
  if (spread) return "--max_views " + std::to_string(m);
  return std::nullopt;
}

std::string ShellQuote(const std::string& arg) {
  const bool plain =
      !arg.empty() && arg.find_first_not_of(
                          "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVW"
                          "XYZ0123456789_./:=,+-@%") == std::string::npos;
  if (plain) return arg;
  std::string out = "'";
  for (const char c : arg)
    out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string ClaimOptions(const std::string& message_text,
                         const std::string& key_option) {
  std::string options = " --message " + ShellQuote(message_text);
  if (!key_option.empty()) options += " --key " + ShellQuote(key_option);
  return options;
}

std::string CommandLine(int argc, char** argv) {
  std::string line = "watergs";
  for (int i = 0; i < argc; ++i) line += " " + ShellQuote(argv[i]);
  return line;
}

ReportFile DescribeFile(const std::string& role, const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  return {role, path, bytes.size(), Fnv1a64(bytes.data(), bytes.size())};
}

OwnershipReport CollectOwnershipReport(
    Rasterizer& rasterizer, const GaussianModel& raw,
    const GaussianModel& watermarked,
    const std::vector<GaussianModel>& suspects, const TrainingViews& views,
    const std::vector<size_t>& eval_views, size_t workspace_views,
    BitDecoder& decoder, const Bits& message, const EvaluationOptions& options,
    EvaluationReport evaluation, const ReportRequest& request) {
  if (suspects.size() != request.suspect_paths.size()) {
    Fail("report: " + std::to_string(suspects.size()) + " suspect models for " +
         std::to_string(request.suspect_paths.size()) + " paths");
  }
  OwnershipReport r;
  r.generator = request.generator;
  r.message_text = request.message_text;
  if (!request.key_option.empty()) {
    r.key_fingerprint = KeyFingerprint(ResolveKey(request.key_option));
  }
  r.watermarked_path = request.watermarked_path;
  r.workspace_path = request.workspace.workspace_path;
  r.workspace_views = workspace_views;
  r.decoder = DescribeFile("decoder", request.decoder_path);
  r.files.push_back(DescribeFile("raw model", request.raw_path));
  r.files.push_back(
      DescribeFile("watermarked model", request.watermarked_path));

  std::vector<RenderCamera> cameras;
  for (size_t view : eval_views) cameras.push_back(views.Camera(view));
  const auto extract = [&](const GaussianModel& model) {
    return ExtractWatermark(rasterizer, model, cameras, evaluation.view_names,
                            decoder, &message, options.background,
                            options.thresholds);
  };
  const RobustnessRow* claim = FindRow(evaluation, "watermarked", "identity");
  OwnerExtraction both;
  if (claim) {
    both.blind = claim->extraction;
    both.owner = claim->owner;
  } else {
    both = ExtractWatermarkWithReference(
        rasterizer, watermarked, raw, cameras, evaluation.view_names, decoder,
        &message, options.background, options.thresholds);
  }
  r.owner_reading = request.owner_reading;
  r.claim = request.owner_reading ? both.owner : both.blind;
  r.claim_other = request.owner_reading ? both.blind : both.owner;
  const RobustnessRow* control = FindRow(evaluation, "raw", "identity");
  r.raw = control ? control->extraction : extract(raw);

  // Suspect copies after the raw model's row.
  for (size_t k = 0; k < suspects.size(); ++k) {
    r.files.push_back(DescribeFile("suspect copy", request.suspect_paths[k]));
    PsnrVsTruth psnr(views, eval_views);
    OwnerExtraction found = ExtractWatermarkWithReference(
        rasterizer, suspects[k], raw, cameras, evaluation.view_names, decoder,
        &message, options.background, options.thresholds, {},
        options.ground_truth ? psnr.Observer() : DecodedViewObserver{});
    const AttackDraw draw = ReadDraw(found.blind, found.owner);
    evaluation.robustness.push_back({"file",
                                     request.suspect_paths[k],
                                     "file",
                                     suspects[k].size(),
                                     std::move(found.blind),
                                     std::move(found.owner),
                                     psnr.Mean(),
                                     {draw}});
  }

  // Views shown in full, spread evenly; their metrics are the evaluation's.
  const size_t n = eval_views.size();
  const size_t shown =
      std::min<size_t>(n, size_t(std::max(0, request.show_views)));
  for (size_t s = 0; s < shown; ++s) {
    const size_t k = s * n / shown;
    const ImageRGB base =
        RenderClamped(rasterizer, raw, cameras[k], options.background);
    const ImageRGB wm =
        RenderClamped(rasterizer, watermarked, cameras[k], options.background);
    ReportView v;
    v.name = evaluation.view_names[k];
    v.render_width = wm.width;
    v.render_height = wm.height;
    v.raw = Shrink(base);
    v.watermarked = Shrink(wm);
    v.difference = Shrink(AmplifiedDifference(wm, base));
    if (k < evaluation.vs_raw.per_view.size()) {
      v.psnr = evaluation.vs_raw.per_view[k].psnr;
      v.ssim = evaluation.vs_raw.per_view[k].ssim;
    }
    v.bit_errors = k < r.claim.views.size() ? r.claim.views[k].bit_errors : -1;
    r.shown.push_back(std::move(v));
  }

  // Commands: extract reads the same cameras when the evaluated views are a
  // selection it makes.
  const std::optional<std::string> view_option =
      ExtractViewsOption(eval_views, workspace_views);
  r.commands = request.commands;
  if (view_option) {
    std::string common =
        " --workspace_path " + ShellQuote(request.workspace.workspace_path);
    if (!request.workspace.input_path.empty()) {
      common += " --sparse_path " + ShellQuote(request.workspace.input_path);
    }
    if (request.workspace.downscale != 1) {
      common += " --downscale " + std::to_string(request.workspace.downscale);
    }
    common += " --decoder " + ShellQuote(request.decoder_path) +
              ClaimOptions(request.message_text, request.key_option);
    if (!view_option->empty()) common += " " + *view_option;
    if (request.background != "0,0,0") {
      common += " --background " + ShellQuote(request.background);
    }
    if (options.thresholds.present_p != VerificationThresholds().present_p) {
      char p[32];
      std::snprintf(p, sizeof(p), "%.17g", options.thresholds.present_p);
      common += std::string(" --false_positive_rate ") + p;
    }
    // A suspect's command reads it as the claim was read (as the owner:
    // minus the raw model's renders); the raw model's reads it blind.
    const std::string owner =
        request.owner_reading ? " --raw_path " + ShellQuote(request.raw_path)
                              : std::string();
    const auto extract_command = [&](const std::string& path) {
      return "watergs extract --input_path " + ShellQuote(path) + common +
             (path == request.raw_path ? std::string() : owner);
    };
    r.commands.push_back({"The claim alone (the verdict above)",
                          extract_command(request.watermarked_path)});
    r.commands.push_back(
        {"The control (the raw model)", extract_command(request.raw_path)});
    // Row k of the evaluation: model attack k (seeded seed + k, as
    // EvaluateWatermark does), then the image attacks, the raw model and the
    // suspect copies.
    size_t model_attack = 0;
    for (const RobustnessRow& row : evaluation.robustness) {
      std::string command;
      if (row.model == "raw") {
        command = extract_command(request.raw_path);
      } else if (row.model == "file") {
        command = extract_command(row.attack);
      } else if (row.kind == "2d") {
        command = extract_command(request.watermarked_path) +
                  " --image_attack " + ShellQuote(row.attack);
      } else if (row.attack == "identity") {
        command = extract_command(request.watermarked_path);
        ++model_attack;
      } else {
        const std::string out =
            "attacked_" + std::to_string(model_attack) + ".ply";
        command = "watergs attack --input_path " +
                  ShellQuote(request.watermarked_path) + " --attack " +
                  ShellQuote(row.attack) + " --seed " +
                  std::to_string(options.seed + model_attack) +
                  " --output_path " + out + " && " + extract_command(out);
        if (row.attack.rfind("similarity:", 0) == 0) {
          command += " --scene_transform " + out + ".transform.txt";
        }
        ++model_attack;
      }
      r.row_commands.push_back(command);
    }
  } else {
    r.commands.push_back(
        {"The " + std::to_string(n) +
             " views evaluated are not a selection watergs extract makes "
             "(it reads all cameras or --max_views N spread evenly): the "
             "command above reproduces every figure; watergs extract "
             "--input_path " +
             request.watermarked_path + " reads the claim on all cameras",
         ""});
  }
  r.evaluation = std::move(evaluation);
  return r;
}

}  // namespace watergs
