// WATER-GS watermark extraction and verification (see extractor.h).
#include "watermark/extractor.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>

#include "gaussian/util/error.h"
#include "watermark/view_aggregation.h"

namespace watergs {

RenderCamera InterpolateCameras(const RenderCamera& a, const RenderCamera& b,
                                double t) {
  RenderCamera cam = a;
  const Eigen::Quaterniond qa(a.R), qb(b.R);
  cam.R = qa.slerp(t, qb).normalized().toRotationMatrix();
  const Eigen::Vector3d center = (1 - t) * a.Center() + t * b.Center();
  cam.t = -cam.R * center;
  return cam;
}

std::vector<RenderCamera> SampleViewpointsBetween(
    const TrainingViews& views, const std::vector<size_t>& train_views, int n,
    uint64_t seed) {
  if (train_views.empty()) Fail("no cameras to sample viewpoints between");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<RenderCamera> out;
  for (int k = 0; k < n; ++k) {
    const size_t a = train_views[rng() % train_views.size()];
    const size_t b = train_views[rng() % train_views.size()];
    out.push_back(
        InterpolateCameras(views.Camera(a), views.Camera(b), uniform(rng)));
  }
  return out;
}

std::vector<RenderCamera> SampleFreeViewpoints(const TrainingViews& views,
                                               int n, uint64_t seed) {
  if (views.NumViews() == 0) Fail("extract: no cameras to sample around");
  std::vector<size_t> all(views.NumViews());
  std::iota(all.begin(), all.end(), size_t(0));
  return SampleViewpointsBetween(views, all, n, seed);
}

ExtractionResult ExtractWatermark(Rasterizer& rasterizer,
                                  const GaussianModel& model,
                                  const std::vector<RenderCamera>& cameras,
                                  const std::vector<std::string>& names,
                                  BitDecoder& decoder, const Bits* expected,
                                  const std::array<float, 3>& background,
                                  const VerificationThresholds& thresholds,
                                  const RenderAttack& attack,
                                  const DecodedViewObserver& observe) {
  const int num_bits = decoder.NumBits();
  if (cameras.empty()) Fail("extract: no views to render");
  if (expected && static_cast<int>(expected->size()) != num_bits) {
    Fail("extract: expected message has " + std::to_string(expected->size()) +
         " bits, the decoder reads " + std::to_string(num_bits));
  }
  RenderOptions options;
  options.background = background;
  ImageRGB image;
  std::vector<ViewDecode> views;
  for (size_t k = 0; k < cameras.size(); ++k) {
    rasterizer.Forward(model, cameras[k], options, &image, nullptr);
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    if (attack) image = attack(image);
    if (observe) observe(k, image);
    ViewDecode view;
    view.name = k < names.size() ? names[k] : "free_" + std::to_string(k);
    view.logits = decoder.Logits(image);
    views.push_back(std::move(view));
  }
  return AggregateViews(std::move(views), num_bits, expected, thresholds);
}

void ResolveOwnerTies(std::vector<float>* difference, const Bits* expected) {
  for (size_t i = 0; i < difference->size(); ++i) {
    float& d = (*difference)[i];
    if (std::abs(d) > kOwnerTieLogit) continue;
    // A tie reads against the claim: no evidence for either bit.
    d = expected ? ((*expected)[i] ? -kOwnerTieLogit : kOwnerTieLogit) : 0.f;
  }
}

std::vector<ViewDecode> DifferenceViews(
    std::vector<ViewDecode> suspect, const std::vector<ViewDecode>& reference,
    const Bits* expected) {
  if (suspect.size() != reference.size()) {
    Fail("owner's reading: " + std::to_string(suspect.size()) +
         " suspect views but " + std::to_string(reference.size()) +
         " reference views");
  }
  for (size_t k = 0; k < suspect.size(); ++k) {
    std::vector<float>& logits = suspect[k].logits;
    const std::vector<float>& raw = reference[k].logits;
    if (logits.size() != raw.size() ||
        (expected && expected->size() != logits.size())) {
      Fail("owner's reading: view " + suspect[k].name +
           " has another number of logits than its reference or message");
    }
    for (size_t i = 0; i < logits.size(); ++i) logits[i] -= raw[i];
    ResolveOwnerTies(&logits, expected);
    suspect[k].bit_errors = -1;
  }
  return suspect;
}

OwnerExtraction ExtractWatermarkWithReference(
    Rasterizer& rasterizer, const GaussianModel& model,
    const GaussianModel& reference, const std::vector<RenderCamera>& cameras,
    const std::vector<std::string>& names, BitDecoder& decoder,
    const Bits* expected, const std::array<float, 3>& background,
    const VerificationThresholds& thresholds, const RenderAttack& attack,
    const DecodedViewObserver& observe,
    const std::vector<RenderCamera>& reference_cameras) {
  OwnerExtraction out;
  out.blind =
      ExtractWatermark(rasterizer, model, cameras, names, decoder, expected,
                       background, thresholds, attack, observe);
  if (!reference_cameras.empty() &&
      reference_cameras.size() != cameras.size()) {
    Fail("owner's reading: " + std::to_string(reference_cameras.size()) +
         " reference cameras for " + std::to_string(cameras.size()) + " views");
  }
  // The reference goes through the suspect's attack too (as detect sends the
  // raw render through the suspect image's JPEG): what the attack does to
  // any render of the scene then cancels, and only the watermark is read.
  const ExtractionResult raw =
      ExtractWatermark(rasterizer, reference,
                       reference_cameras.empty() ? cameras : reference_cameras,
                       names, decoder, nullptr, background, thresholds, attack);
  out.owner =
      AggregateViews(DifferenceViews(out.blind.views, raw.views, expected),
                     decoder.NumBits(), expected, thresholds);
  return out;
}

std::string ExtractionToJson(const ExtractionResult& r) {
  nlohmann::json j;
  j["num_bits"] = r.recovered.size();
  j["recovered_hex"] = BitsToHex(r.recovered);
  j["recovered_bits"] = BitsToString(r.recovered);
  j["num_views"] = r.views.size();
  j["mean_logits"] = r.mean_logits;
  if (r.has_expected) {
    j["expected_bits"] = BitsToString(r.expected);
    j["bit_errors"] = r.bit_errors;
    j["ber"] = r.ber;
    j["view_ber"] = {{"mean", r.mean_view_ber},
                     {"median", r.median_view_ber},
                     {"p90", r.p90_view_ber},
                     {"min", r.min_view_ber},
                     {"max", r.max_view_ber}};
    j["p_value"] = r.p_value;
    j["verdict"] = ToString(r.verdict);
    j["false_positive_rate"] = r.thresholds.present_p;
    j["absent_above_p"] = r.thresholds.absent_p;
  }
  nlohmann::json views = nlohmann::json::array();
  for (const ViewDecode& v : r.views) {
    nlohmann::json e = {{"name", v.name}};
    if (v.bit_errors >= 0) e["bit_errors"] = v.bit_errors;
    e["logits"] = v.logits;
    views.push_back(e);
  }
  j["views"] = views;
  return j.dump(2) + "\n";
}

}  // namespace watergs
