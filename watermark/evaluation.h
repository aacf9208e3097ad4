// Evaluation of a watermarked 3DGS model against its raw original, as the
// paper reports it and beyond: image quality of the watermarked renders
// (PSNR, SSIM, MS-SSIM, VGG-LPIPS) against ground truth and against the raw
// model's renders, and the watermark's bit error rate, p-value and verdict
// under each model attack (the paper's 3D distortions and the file attacks
// of distortion/file_attacks.h) and each attack on the rendered images
// (watermark/image_attacks.h). Reports as JSON and Markdown.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "distortion/file_attacks.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"
#include "watermark/lpips.h"

namespace watergs {

// The paper's distortions at its default strengths, then the file attacks.
inline constexpr char kDefaultModelAttacks[] =
    "identity,gn:0.01,dropout:0.1,crop:0.1,sh0,fp16,quant:8,shuffle,"
    "similarity:30,0.1,-0.2,0.3,1.5,1,1,1,prune:0.05";
inline constexpr char kDefaultImageAttacks[] =
    "jpeg:75,jpeg:50,resize:0.5,crop:0.5";
// kDefaultModelAttacks parsed.
std::vector<ModelAttackSpec> DefaultModelAttacks();
// kDefaultImageAttacks parsed.
std::vector<ImageAttackSpec> DefaultImageAttacks();

struct EvaluationOptions {
  // Colour behind the Gaussians.
  std::array<float, 3> background = {0.f, 0.f, 0.f};
  // Attacks on the watermarked model (each applied alone to the original).
  std::vector<ModelAttackSpec> model_attacks = DefaultModelAttacks();
  // Attacks on the watermarked model's renders.
  std::vector<ImageAttackSpec> image_attacks = DefaultImageAttacks();
  // Verdict thresholds.
  VerificationThresholds thresholds;
  // Seeds the random attacks (attack k's first draw uses seed + k).
  uint64_t seed = 0;
  // Draws of each attack whose renders depend on the draw
  // (AttackRendersPerDraw): the paper's Table 1 reads one; a crop removes
  // one contiguous run of the file, so one draw is a sample, not a bound.
  int attack_draws = 1;
  // LPIPS network, or null: the LPIPS column is then empty, `lpips_note`
  // says why.
  Lpips* lpips = nullptr;
  std::string lpips_note;
  // Whether `views` has ground-truth images; without, the two comparisons
  // against them are left empty (n/a) and `ground_truth_note` says why.
  bool ground_truth = true;
  std::string ground_truth_note;
  // Draw a progress bar with ETA on stderr.
  bool show_progress = false;
};

// Metrics of one image against a reference.
struct QualityMetrics {
  double psnr = 0, ssim = 0, ms_ssim = 0;
  // Scales MS-SSIM used (5 unless the image is small).
  int ms_ssim_scales = 0;
  // LPIPS, valid only when has_lpips.
  bool has_lpips = false;
  double lpips = 0;
};

// One comparison ("watermarked vs ground truth", ...), mean over views.
struct QualityComparison {
  // What is compared, for the report.
  std::string label;
  // Mean over views (Inria averages per-image metrics).
  QualityMetrics mean;
  // Per view, in the order of EvaluationReport::view_names.
  std::vector<QualityMetrics> per_view;
};

// One draw of an attack, read blind and as the owner.
struct AttackDraw {
  // Mean over views of each view's BER (the paper's per-image BER).
  double view_ber = 0, owner_view_ber = 0;
  // Wrong bits of the mean logits over the views.
  int bit_errors = 0, owner_bit_errors = 0;
  // The verdict on the views aggregated, blind and as the owner: what an
  // owner shows for this draw.
  Verdict verdict = Verdict::kInconclusive,
          owner_verdict = Verdict::kInconclusive;
};

// The draw read blind as `blind` and as the owner as `owner`.
AttackDraw ReadDraw(const ExtractionResult& blind,
                    const ExtractionResult& owner);

// Mean, smallest and largest of a figure over draws.
struct DrawSpread {
  double mean = 0, min = 0, max = 0;
};
DrawSpread SpreadOver(const std::vector<AttackDraw>& draws,
                      const std::function<double(const AttackDraw&)>& figure);
// Draws whose aggregated verdict (blind, or as the owner) is `verdict`.
int CountDraws(const std::vector<AttackDraw>& draws, bool owner,
               Verdict verdict);

// The watermark under one attack.
struct RobustnessRow {
  // "watermarked" or "raw" (the false-positive check).
  std::string model;
  // The attack's text ("identity", "jpeg:50", ...).
  std::string attack;
  // "3d" (model attack) or "2d" (attack on renders).
  std::string kind;
  // Gaussians rendered.
  size_t num_gaussians = 0;
  // Extraction against the message: blind, and the owner's reading (each
  // view's logits minus the raw model's at the same viewpoint, through the
  // same attack on renders for a "2d" row; extractor.h).
  ExtractionResult extraction;
  ExtractionResult owner;
  // Mean PSNR (dB) over the views of what was decoded (the attacked model's
  // renders, after the image attack) against the ground truth: a row whose
  // scene is gone reads as such. NaN without ground truth.
  double psnr = NAN;
  // Every draw's figures, the first being `extraction` and `owner`'s (one
  // entry unless the attack renders per draw and attack_draws > 1).
  std::vector<AttackDraw> draws;
};

struct EvaluationReport {
  // Gaussians in the raw and watermarked models.
  size_t raw_gaussians = 0, watermarked_gaussians = 0;
  // The evaluated views' names.
  std::vector<std::string> view_names;
  // The message and its length.
  Bits message;
  // Watermarked vs ground truth, watermarked vs raw renders, raw vs ground
  // truth (context: what the raw model itself reaches).
  QualityComparison vs_ground_truth, vs_raw, raw_vs_ground_truth;
  // Why the comparisons against ground truth are empty ("" when computed).
  std::string ground_truth_note;
  // Why LPIPS is empty ("" when computed).
  std::string lpips_note;
  // One row per attack, the raw model's identity row last.
  std::vector<RobustnessRow> robustness;
  // Verdict thresholds used.
  VerificationThresholds thresholds;
  // Draws of each attack that renders per draw.
  int attack_draws = 1;
  // Wall time of the evaluation.
  double seconds = 0;
};

// The render of `model` from `camera`, clamped to [0, 1] as images are
// compared and decoded (also by the ownership report).
ImageRGB RenderClamped(Rasterizer& rasterizer, const GaussianModel& model,
                       const RenderCamera& camera,
                       const std::array<float, 3>& background);

// Mean PSNR (dB) against the ground truth of the images a row decoded: fed
// by ExtractWatermark's observer, so the renders are not made twice. Image k
// is compared with views.Image(view_ids[k]); one whose size the attack
// changed is compared with the truth under the same attack.
class PsnrVsTruth {
 public:
  PsnrVsTruth(const TrainingViews& views, const std::vector<size_t>& view_ids,
              RenderAttack attack = {});
  DecodedViewObserver Observer();
  // NaN until every view has been seen once.
  double Mean() const;

 private:
  const TrainingViews& views_;
  const std::vector<size_t>& view_ids_;
  RenderAttack attack_;
  double sum_ = 0;
  size_t seen_ = 0;
};

// Evaluates on `eval_views` (indices into `views`). The raw and watermarked
// models are rendered from the same cameras; a similarity attack moves the
// cameras with the scene. `message` must have the decoder's length.
EvaluationReport EvaluateWatermark(Rasterizer& rasterizer,
                                   const GaussianModel& raw,
                                   const GaussianModel& watermarked,
                                   const TrainingViews& views,
                                   const std::vector<size_t>& eval_views,
                                   BitDecoder& decoder, const Bits& message,
                                   const EvaluationOptions& options);

// The report as JSON (per-view metrics and per-attack results included);
// non-finite numbers (PSNR of identical images) are written as null.
std::string EvaluationToJson(const EvaluationReport& report);
// The report as Markdown: a quality table and a robustness table.
std::string EvaluationToMarkdown(const EvaluationReport& report);

}  // namespace watergs
