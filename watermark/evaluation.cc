// Evaluation of a watermarked model (see evaluation.h).
#include "watermark/evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "gaussian/loss.h"
#include "gaussian/util/error.h"
#include "gaussian/util/progress.h"
#include "watermark/image_quality.h"
#include "watermark/view_aggregation.h"

namespace watergs {
namespace {

// Metrics of `image` against `reference`; LPIPS from precomputed features.
QualityMetrics Compare(const ImageRGB& image, const ImageRGB& reference,
                       const Lpips* lpips,
                       const Lpips::Features* image_features,
                       const Lpips::Features* reference_features) {
  QualityMetrics m;
  m.psnr = Psnr(image, reference);
  m.ssim = Ssim(image, reference);
  const MsSsimResult ms = MsSsim(image, reference);
  m.ms_ssim = ms.value;
  m.ms_ssim_scales = ms.scales;
  if (lpips && image_features && reference_features) {
    m.has_lpips = true;
    m.lpips = lpips->Distance(*image_features, *reference_features);
  }
  return m;
}

void Accumulate(const QualityMetrics& view, size_t count,
                QualityComparison* comparison) {
  comparison->per_view.push_back(view);
  QualityMetrics& mean = comparison->mean;
  mean.psnr += view.psnr / count;
  mean.ssim += view.ssim / count;
  mean.ms_ssim += view.ms_ssim / count;
  mean.ms_ssim_scales = view.ms_ssim_scales;
  mean.has_lpips = view.has_lpips;
  mean.lpips += view.lpips / count;
}

nlohmann::json Number(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
}

nlohmann::json MetricsJson(const QualityMetrics& m) {
  return {{"psnr", Number(m.psnr)},
          {"ssim", Number(m.ssim)},
          {"ms_ssim", Number(m.ms_ssim)},
          {"ms_ssim_scales", m.ms_ssim_scales},
          {"lpips", m.has_lpips ? Number(m.lpips) : nlohmann::json()}};
}

std::string Format(const char* format, double value) {
  if (!std::isfinite(value)) return std::isinf(value) ? "inf" : "n/a";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

// The random stream of draw `draw` of model attack `attack`: the first
// draw keeps the seed + k of one-draw evaluations.
std::mt19937_64 DrawRng(uint64_t seed, size_t attack, int draw) {
  if (draw == 0) return std::mt19937_64(seed + attack);
  // seed_seq keeps 32 bits of each value: the seed goes in as two.
  std::seed_seq seq{uint32_t(seed), uint32_t(seed >> 32), uint32_t(attack),
                    uint32_t(draw)};
  return std::mt19937_64(seq);
}

nlohmann::json SpreadJson(const DrawSpread& spread) {
  return {{"mean", spread.mean}, {"min", spread.min}, {"max", spread.max}};
}

// A draw's figures as the owner (`owner`) or blind.
nlohmann::json DrawJson(const AttackDraw& d, bool owner) {
  return {{"view_ber", owner ? d.owner_view_ber : d.view_ber},
          {"bit_errors", owner ? d.owner_bit_errors : d.bit_errors},
          {"verdict", ToString(owner ? d.owner_verdict : d.verdict)}};
}

// A row's draws: each figure's mean, min and max over them, how many draws
// read each verdict, and every draw's figures in draw order (draw d does not
// depend on how many were drawn: the first 8 of 32 are an 8-draw run).
nlohmann::json DrawsJson(const std::vector<AttackDraw>& draws) {
  nlohmann::json j = {{"count", draws.size()}};
  for (const bool owner : {false, true}) {
    nlohmann::json side = {
        {"view_ber", SpreadJson(SpreadOver(draws,
                                           [owner](const AttackDraw& d) {
                                             return owner ? d.owner_view_ber
                                                          : d.view_ber;
                                           }))},
        {"bit_errors",
         SpreadJson(SpreadOver(draws, [owner](const AttackDraw& d) {
           return double(owner ? d.owner_bit_errors : d.bit_errors);
         }))}};
    side["verdicts"] = {
        {"present", CountDraws(draws, owner, Verdict::kPresent)},
        {"inconclusive", CountDraws(draws, owner, Verdict::kInconclusive)},
        {"absent", CountDraws(draws, owner, Verdict::kAbsent)}};
    nlohmann::json per_draw = nlohmann::json::array();
    for (const AttackDraw& d : draws) per_draw.push_back(DrawJson(d, owner));
    side["per_draw"] = per_draw;
    if (owner) {
      j["owner"] = side;
    } else {
      j.update(side);
    }
  }
  return j;
}

}  // namespace

DrawSpread SpreadOver(const std::vector<AttackDraw>& draws,
                      const std::function<double(const AttackDraw&)>& figure) {
  DrawSpread spread;
  if (draws.empty()) return spread;
  spread.min = spread.max = figure(draws[0]);
  for (const AttackDraw& draw : draws) {
    const double value = figure(draw);
    spread.mean += value / double(draws.size());
    spread.min = std::min(spread.min, value);
    spread.max = std::max(spread.max, value);
  }
  return spread;
}

AttackDraw ReadDraw(const ExtractionResult& blind,
                    const ExtractionResult& owner) {
  return {blind.mean_view_ber, owner.mean_view_ber, blind.bit_errors,
          owner.bit_errors,    blind.verdict,       owner.verdict};
}

int CountDraws(const std::vector<AttackDraw>& draws, bool owner,
               Verdict verdict) {
  return int(std::count_if(draws.begin(), draws.end(), [&](const auto& d) {
    return (owner ? d.owner_verdict : d.verdict) == verdict;
  }));
}

ImageRGB RenderClamped(Rasterizer& rasterizer, const GaussianModel& model,
                       const RenderCamera& camera,
                       const std::array<float, 3>& background) {
  RenderOptions options;
  options.background = background;
  ImageRGB image;
  rasterizer.Forward(model, camera, options, &image, nullptr);
  for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
  return image;
}

std::vector<ModelAttackSpec> DefaultModelAttacks() {
  return ParseModelAttackList(kDefaultModelAttacks);
}

std::vector<ImageAttackSpec> DefaultImageAttacks() {
  return ParseImageAttackList(kDefaultImageAttacks);
}

PsnrVsTruth::PsnrVsTruth(const TrainingViews& views,
                         const std::vector<size_t>& view_ids,
                         RenderAttack attack)
    : views_(views), view_ids_(view_ids), attack_(std::move(attack)) {}

DecodedViewObserver PsnrVsTruth::Observer() {
  return [this](size_t k, const ImageRGB& decoded) {
    if (k >= view_ids_.size()) {
      Fail("eval: PSNR of camera " + std::to_string(k) + " for " +
           std::to_string(view_ids_.size()) + " views");
    }
    const std::shared_ptr<const ImageRGB> truth = views_.Image(view_ids_[k]);
    const bool same_size =
        decoded.width == truth->width && decoded.height == truth->height;
    // An attack that resizes or crops the render: the truth under the same
    // geometry (JPEG keeps the size, so its artefacts always count).
    sum_ += same_size || !attack_ ? Psnr(decoded, *truth)
                                  : Psnr(decoded, attack_(*truth));
    ++seen_;
  };
}

double PsnrVsTruth::Mean() const {
  return seen_ == view_ids_.size() && seen_ > 0 ? sum_ / double(seen_) : NAN;
}

EvaluationReport EvaluateWatermark(Rasterizer& rasterizer,
                                   const GaussianModel& raw,
                                   const GaussianModel& watermarked,
                                   const TrainingViews& views,
                                   const std::vector<size_t>& eval_views,
                                   BitDecoder& decoder, const Bits& message,
                                   const EvaluationOptions& options) {
  if (eval_views.empty()) Fail("eval: no views to evaluate");
  if (options.attack_draws < 1) Fail("eval: --attack_draws must be >= 1");
  const auto begin = std::chrono::steady_clock::now();
  EvaluationReport report;
  report.raw_gaussians = raw.size();
  report.watermarked_gaussians = watermarked.size();
  report.message = message;
  report.thresholds = options.thresholds;
  report.attack_draws = options.attack_draws;
  report.lpips_note = options.lpips ? "" : options.lpips_note;
  report.ground_truth_note =
      options.ground_truth ? "" : options.ground_truth_note;
  report.vs_ground_truth.label = "watermarked vs ground truth";
  report.vs_raw.label = "watermarked vs raw renders";
  report.raw_vs_ground_truth.label = "raw vs ground truth";
  const size_t n = eval_views.size();
  size_t num_attacks = options.image_attacks.size() + 1;
  for (const ModelAttackSpec& spec : options.model_attacks) {
    num_attacks += AttackRendersPerDraw(spec) ? options.attack_draws : 1;
  }
  ProgressBar progress("eval", int64_t(n * (1 + num_attacks)));
  const auto step = [&](int64_t done, const std::string& what) {
    if (options.show_progress) progress.Update(done, what);
  };

  std::vector<RenderCamera> cameras;
  for (size_t view : eval_views) {
    report.view_names.push_back(views.Name(view));
    cameras.push_back(views.Camera(view));
  }
  Lpips* lpips = options.lpips;
  if (lpips && (cameras[0].width < 16 || cameras[0].height < 16)) {
    lpips = nullptr;
    report.lpips_note = "not computed: images smaller than 16x16 pixels";
  }
  for (size_t k = 0; k < n; ++k) {
    const ImageRGB wm =
        RenderClamped(rasterizer, watermarked, cameras[k], options.background);
    const ImageRGB base =
        RenderClamped(rasterizer, raw, cameras[k], options.background);
    Lpips::Features f_wm, f_base, f_truth;
    if (lpips) {
      f_wm = lpips->Extract(wm);
      f_base = lpips->Extract(base);
    }
    Accumulate(Compare(wm, base, lpips, &f_wm, &f_base), n, &report.vs_raw);
    if (options.ground_truth) {
      const std::shared_ptr<const ImageRGB> truth_image =
          views.Image(eval_views[k]);
      const ImageRGB& truth = *truth_image;
      if (lpips) f_truth = lpips->Extract(truth);
      Accumulate(Compare(wm, truth, lpips, &f_wm, &f_truth), n,
                 &report.vs_ground_truth);
      Accumulate(Compare(base, truth, lpips, &f_base, &f_truth), n,
                 &report.raw_vs_ground_truth);
    }
    step(int64_t(k + 1), "quality");
  }
  if (!options.ground_truth) {
    // No views compared: the means are not numbers (n/a, null in JSON).
    for (QualityComparison* c :
         {&report.vs_ground_truth, &report.raw_vs_ground_truth}) {
      c->mean.psnr = c->mean.ssim = c->mean.ms_ssim = NAN;
      c->mean.ms_ssim_scales = report.vs_raw.mean.ms_ssim_scales;
    }
  }

  int64_t done = int64_t(n);
  // Decodes a row; its PSNR against the ground truth comes from the same
  // renders (NaN without ground truth).
  struct Row {
    ExtractionResult extraction;
    double psnr;
  };
  const auto extract = [&](const GaussianModel& model,
                           const std::vector<RenderCamera>& render_cameras,
                           const RenderAttack& attack) {
    PsnrVsTruth psnr(views, eval_views, attack);
    Row row{ExtractWatermark(
                rasterizer, model, render_cameras, report.view_names, decoder,
                &message, options.background, options.thresholds, attack,
                options.ground_truth ? psnr.Observer() : DecodedViewObserver{}),
            NAN};
    row.psnr = psnr.Mean();
    return row;
  };
  // The raw model's logits at the evaluated cameras: the owner's reading
  // of every 3D row subtracts them (a moved scene's cameras see the same
  // view); a 2D row subtracts them through its own attack (below).
  const std::vector<ViewDecode> raw_views =
      ExtractWatermark(rasterizer, raw, cameras, report.view_names, decoder,
                       nullptr, options.background, options.thresholds)
          .views;
  const auto owner_of = [&](const ExtractionResult& extraction,
                            const std::vector<ViewDecode>* reference_views =
                                nullptr) {
    done += int64_t(n);
    return AggregateViews(
        DifferenceViews(extraction.views,
                        reference_views ? *reference_views : raw_views,
                        &message),
        decoder.NumBits(), &message, options.thresholds);
  };
  // `draws`: the figures of the draws after the first (random attacks).
  const auto add_row =
      [&](std::string model, std::string attack, std::string kind,
          size_t gaussians, Row row, std::vector<AttackDraw> draws = {},
          const std::vector<ViewDecode>* reference_views = nullptr) {
        ExtractionResult owner = owner_of(row.extraction, reference_views);
        draws.insert(draws.begin(), ReadDraw(row.extraction, owner));
        char status[96];
        std::snprintf(status, sizeof(status), "%s BER %.1f%%", attack.c_str(),
                      100 * row.extraction.ber);
        step(done, status);
        report.robustness.push_back(
            {std::move(model), std::move(attack), std::move(kind), gaussians,
             std::move(row.extraction), std::move(owner), row.psnr,
             std::move(draws)});
      };
  // The cameras an attack that renders the scene (prune_significance) sees:
  // the views not evaluated, the training split when the evaluated ones are
  // held out; all of them when every view is evaluated.
  std::vector<RenderCamera> training_cameras;
  {
    std::vector<bool> evaluated(views.NumViews(), false);
    for (size_t view : eval_views) evaluated[view] = true;
    for (size_t v = 0; v < views.NumViews(); ++v) {
      if (!evaluated[v]) training_cameras.push_back(views.Camera(v));
    }
    if (training_cameras.empty()) training_cameras = cameras;
  }
  for (size_t a = 0; a < options.model_attacks.size(); ++a) {
    const ModelAttackSpec& spec = options.model_attacks[a];
    std::vector<RenderCamera> moved = cameras;
    if (spec.kind == ModelAttackKind::kSimilarity) {
      for (RenderCamera& c : moved) c = TransformCamera(c, spec.similarity);
    }
    const auto draw = [&](int d) {
      std::mt19937_64 rng = DrawRng(options.seed, a, d);
      GaussianModel attacked;
      std::vector<uint32_t> source;
      ApplyModelAttack(spec, watermarked, rng, &attacked, &source,
                       &training_cameras);
      return std::make_pair(attacked.size(), extract(attacked, moved, {}));
    };
    const int num_draws = AttackRendersPerDraw(spec) ? options.attack_draws : 1;
    auto [gaussians, first] = draw(0);
    std::vector<AttackDraw> later;
    for (int d = 1; d < num_draws; ++d) {
      const ExtractionResult blind = draw(d).second.extraction;
      later.push_back(ReadDraw(blind, owner_of(blind)));
      step(done, ToString(spec) + " draw " + std::to_string(d + 1));
    }
    add_row("watermarked", ToString(spec), "3d", gaussians, std::move(first),
            std::move(later));
  }
  for (const ImageAttackSpec& spec : options.image_attacks) {
    const RenderAttack attack = [spec](const ImageRGB& image) {
      return AttackAsDecoded(spec, image);
    };
    // The owner's reference through the same image attack (extractor.h).
    const std::vector<ViewDecode> attacked_raw =
        ExtractWatermark(rasterizer, raw, cameras, report.view_names, decoder,
                         nullptr, options.background, options.thresholds,
                         attack)
            .views;
    add_row("watermarked", ToString(spec), "2d", watermarked.size(),
            extract(watermarked, cameras, attack), {}, &attacked_raw);
  }
  add_row("raw", "identity", "3d", raw.size(), extract(raw, cameras, {}));
  if (options.show_progress) progress.Finish();
  report.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin)
          .count();
  return report;
}

std::string EvaluationToJson(const EvaluationReport& r) {
  nlohmann::json j;
  j["raw_gaussians"] = r.raw_gaussians;
  j["watermarked_gaussians"] = r.watermarked_gaussians;
  j["num_bits"] = r.message.size();
  j["message_bits"] = BitsToString(r.message);
  j["views"] = r.view_names;
  j["false_positive_rate"] = r.thresholds.present_p;
  j["absent_above_p"] = r.thresholds.absent_p;
  j["lpips_note"] = r.lpips_note;
  j["ground_truth_note"] = r.ground_truth_note;
  j["seconds"] = r.seconds;
  j["attack_draws"] = r.attack_draws;
  nlohmann::json quality = nlohmann::json::array();
  for (const QualityComparison* c :
       {&r.vs_ground_truth, &r.vs_raw, &r.raw_vs_ground_truth}) {
    nlohmann::json per_view = nlohmann::json::array();
    for (const QualityMetrics& m : c->per_view) {
      per_view.push_back(MetricsJson(m));
    }
    quality.push_back({{"comparison", c->label},
                       {"mean", MetricsJson(c->mean)},
                       {"per_view", per_view}});
  }
  j["quality"] = quality;
  nlohmann::json rows = nlohmann::json::array();
  for (const RobustnessRow& row : r.robustness) {
    const ExtractionResult& e = row.extraction;
    rows.push_back({{"model", row.model},
                    {"attack", row.attack},
                    {"kind", row.kind},
                    {"gaussians", row.num_gaussians},
                    {"psnr", std::isnan(row.psnr) ? nlohmann::json(nullptr)
                                                  : nlohmann::json(row.psnr)},
                    {"ber", e.ber},
                    {"bit_errors", e.bit_errors},
                    {"view_ber",
                     {{"mean", e.mean_view_ber},
                      {"median", e.median_view_ber},
                      {"p90", e.p90_view_ber},
                      {"min", e.min_view_ber},
                      {"max", e.max_view_ber}}},
                    {"p_value", e.p_value},
                    {"verdict", ToString(e.verdict)},
                    {"recovered_hex", BitsToHex(e.recovered)},
                    {"owner",
                     {{"ber", row.owner.ber},
                      {"bit_errors", row.owner.bit_errors},
                      {"view_ber",
                       {{"mean", row.owner.mean_view_ber},
                        {"median", row.owner.median_view_ber},
                        {"p90", row.owner.p90_view_ber},
                        {"min", row.owner.min_view_ber},
                        {"max", row.owner.max_view_ber}}},
                      {"p_value", row.owner.p_value},
                      {"verdict", ToString(row.owner.verdict)}}}});
    if (row.draws.size() > 1) rows.back()["draws"] = DrawsJson(row.draws);
  }
  j["robustness"] = rows;
  return j.dump(2) + "\n";
}

namespace {

// The rows drawn more than once: each figure's mean and range over draws.
std::string DrawsMarkdown(const EvaluationReport& r) {
  std::ostringstream out;
  const auto cell = [](const DrawSpread& s, double scale, const char* format) {
    return Format(format, scale * s.mean) + " (" +
           Format(format, scale * s.min) + "-" + Format(format, scale * s.max) +
           ")";
  };
  for (const RobustnessRow& row : r.robustness) {
    if (row.draws.size() < 2) continue;
    if (out.tellp() == 0) {
      out << "\n## Over " << r.attack_draws
          << " draws of each random attack (mean (min-max) over draws; "
             "present: draws whose aggregated views read 'present')\n\n"
          << "| Attack | Single view BER mean (%) | Bit errors | Present | "
             "Owner: single view BER mean (%) | Owner: bit errors | Owner: "
             "present |\n"
          << "|---|---:|---:|---:|---:|---:|---:|\n";
    }
    const auto& d = row.draws;
    const auto present = [&](bool owner) {
      return std::to_string(CountDraws(d, owner, Verdict::kPresent)) + " of " +
             std::to_string(d.size());
    };
    out << "| " << row.attack << " | "
        << cell(SpreadOver(d, [](const AttackDraw& x) { return x.view_ber; }),
                100, "%.2f")
        << " | "
        << cell(
               SpreadOver(
                   d, [](const AttackDraw& x) { return double(x.bit_errors); }),
               1, "%.1f")
        << " | " << present(false) << " | "
        << cell(SpreadOver(
                    d, [](const AttackDraw& x) { return x.owner_view_ber; }),
                100, "%.2f")
        << " | "
        << cell(SpreadOver(d,
                           [](const AttackDraw& x) {
                             return double(x.owner_bit_errors);
                           }),
                1, "%.1f")
        << " | " << present(true) << " |\n";
  }
  return out.str();
}

}  // namespace

std::string EvaluationToMarkdown(const EvaluationReport& r) {
  std::ostringstream out;
  out << "## Image quality (mean over " << r.view_names.size()
      << (r.view_names.size() == 1 ? " view" : " views") << ")\n\n"
      << "| Comparison | PSNR (dB) | SSIM | MS-SSIM | LPIPS (VGG) |\n"
      << "|---|---:|---:|---:|---:|\n";
  for (const QualityComparison* c :
       {&r.vs_ground_truth, &r.vs_raw, &r.raw_vs_ground_truth}) {
    const QualityMetrics& m = c->mean;
    out << "| " << c->label << " | " << Format("%.2f", m.psnr) << " | "
        << Format("%.4f", m.ssim) << " | " << Format("%.4f", m.ms_ssim) << " | "
        << (m.has_lpips ? Format("%.4f", m.lpips) : "") << " |\n";
  }
  out << "\n";
  if (!r.ground_truth_note.empty()) {
    out << "Ground truth: " << r.ground_truth_note << ".\n";
  }
  if (!r.lpips_note.empty()) out << "LPIPS: " << r.lpips_note << ".\n";
  const int scales = r.vs_raw.mean.ms_ssim_scales;
  if (scales < 5) {
    out << "MS-SSIM: " << scales
        << " scale(s), the image is too small for 5 (weights renormalised).\n";
  }
  out << "\n## Watermark (" << r.message.size()
      << " bits; present at p <= " << Format("%.0e", r.thresholds.present_p)
      << ")\n\n"
      << "| Model | Attack | Kind | Gaussians | PSNR vs truth (dB) | "
         "Aggregated "
         "BER (%) | Bit errors | p-value | Verdict | Single view BER mean / "
         "median / p90 (%) |\n"
      << "|---|---|---|---:|---:|---:|---:|---:|---|---:|\n";
  for (const RobustnessRow& row : r.robustness) {
    const ExtractionResult& e = row.extraction;
    out << "| " << row.model << " | " << row.attack << " | " << row.kind
        << " | " << row.num_gaussians << " | " << Format("%.2f", row.psnr)
        << " | " << Format("%.2f", 100 * e.ber) << " | " << e.bit_errors
        << " | " << Format("%.3g", e.p_value) << " | " << ToString(e.verdict)
        << " | " << Format("%.1f", 100 * e.mean_view_ber) << " / "
        << Format("%.1f", 100 * e.median_view_ber) << " / "
        << Format("%.1f", 100 * e.p90_view_ber) << " |\n";
  }
  out << "\n## The owner's reading (each view's logits minus the raw model's "
         "at the same viewpoint)\n\n"
      << "| Model | Attack | Aggregated BER (%) | Bit errors | p-value | "
         "Verdict | Single view BER mean / median / p90 (%) |\n"
      << "|---|---|---:|---:|---:|---|---:|\n";
  for (const RobustnessRow& row : r.robustness) {
    const ExtractionResult& e = row.owner;
    out << "| " << row.model << " | " << row.attack << " | "
        << Format("%.2f", 100 * e.ber) << " | " << e.bit_errors << " | "
        << Format("%.3g", e.p_value) << " | " << ToString(e.verdict) << " | "
        << Format("%.1f", 100 * e.mean_view_ber) << " / "
        << Format("%.1f", 100 * e.median_view_ber) << " / "
        << Format("%.1f", 100 * e.p90_view_ber) << " |\n";
  }
  out << DrawsMarkdown(r);
  return out.str();
}

}  // namespace watergs
