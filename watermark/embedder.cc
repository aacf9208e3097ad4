// WATER-GS watermark embedding (see embedder.h).
#include "watermark/embedder.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "gaussian/checkpoint.h"
#include "gaussian/projection.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "watermark/backend.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"
#include "watermark/texture_masking.h"

namespace watergs {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// The options two run signatures (JSON objects) disagree on, as
// "crop_size 0 then, 384 now; ..." ("" when either is not an object).
std::string SignatureDifferences(const std::string& then_text,
                                 const std::string& now_text) {
  const auto then = nlohmann::json::parse(then_text, nullptr, false);
  const auto now = nlohmann::json::parse(now_text, nullptr, false);
  if (!then.is_object() || !now.is_object()) return "";
  auto value_in = [](const nlohmann::json& j, const std::string& key) {
    return j.contains(key) ? j[key].dump() : std::string("unset");
  };
  std::string out;
  nlohmann::json keys = then;
  keys.update(now);
  for (const auto& item : keys.items()) {
    const std::string then_value = value_in(then, item.key());
    const std::string now_value = value_in(now, item.key());
    if (then_value == now_value) continue;
    if (!out.empty()) out += "; ";
    out += item.key() + " " + then_value + " then, " + now_value + " now";
  }
  return out;
}

int CountBitErrors(const std::vector<float>& logits, const Bits& message) {
  // Logit > 0 reads bit 1.
  int errors = 0;
  for (size_t i = 0; i < message.size(); ++i) {
    errors += (logits[i] > 0 ? 1 : 0) != message[i];
  }
  return errors;
}

// The smallest signed logit over the bits: how far past zero the weakest
// bit reads its message bit (negative when some bit reads wrong).
double WeakestMargin(const std::vector<float>& logits, const Bits& message) {
  double weakest = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < message.size(); ++i) {
    weakest = std::min(weakest, double(message[i] ? logits[i] : -logits[i]));
  }
  return weakest;
}

// The owner's reading of a view's `logits`: minus the input model's at the
// same viewpoint, ties read against the claim (as extract --raw_path reads).
void SubtractReference(const std::vector<float>& raw, const Bits& message,
                       std::vector<float>* logits) {
  for (size_t i = 0; i < logits->size(); ++i) (*logits)[i] -= raw[i];
  ResolveOwnerTies(logits, &message);
}

}  // namespace

std::array<bool, kNumParamGroups> ParseParamMask(const std::string& text) {
  std::array<bool, kNumParamGroups> mask{};
  if (text == "ALL" || text == "all") {
    mask.fill(true);
    return mask;
  }
  std::istringstream in(text);
  std::string name;
  bool any = false;
  while (std::getline(in, name, ',')) {
    bool found = false;
    for (int g = 0; g < kNumParamGroups; ++g) {
      if (name == GroupName(static_cast<ParamGroup>(g))) {
        mask[g] = true;
        found = any = true;
      }
    }
    if (!found) {
      Fail("--mask: unknown parameter group '" + name +
           "' (use ALL or xyz,f_dc,f_rest,opacity,scaling,rotation)");
    }
  }
  if (!any) Fail("--mask: no parameter group given");
  return mask;
}

EmbedOptions DefaultEmbedOptions(int64_t iterations) {
  EmbedOptions o;
  o.iterations = iterations;
  o.adam.position_lr_init = 1.6e-5;
  o.adam.position_lr_final = 1.6e-6;
  o.adam.position_lr_max_steps = iterations;
  o.density.densify_from_iter = 100;
  o.density.densify_until_iter = iterations / 2;
  o.density.opacity_reset_interval = iterations + 1;
  return o;
}

void EmbedTimings::Add(const EmbedTimings& o) {
  distortion += o.distortion;
  render += o.render;
  image_loss += o.image_loss;
  decoder += o.decoder;
  backward += o.backward;
  density += o.density;
  adam += o.adam;
}

Embedder::Embedder(const EmbedOptions& options, const TrainingViews& views,
                   std::vector<size_t> train_views, GaussianModel model,
                   double scene_extent, BitDecoder* decoder, Bits message,
                   std::unique_ptr<Rasterizer> rasterizer)
    : options_(options),
      views_(views),
      train_views_(std::move(train_views)),
      model_(std::move(model)),
      scene_extent_(scene_extent),
      decoder_(decoder),
      message_(std::move(message)),
      rasterizer_(std::move(rasterizer)),
      adam_(options.adam, scene_extent),
      loss_(options.beta),
      rng_(options.seed) {
  if (train_views_.empty()) Fail("embed: no training views");
  for (size_t v : train_views_) {
    if (v >= views_.NumViews()) Fail("embed: view index out of range");
  }
  if (static_cast<int>(message_.size()) != decoder_->NumBits()) {
    Fail("embed: message has " + std::to_string(message_.size()) +
         " bits, the decoder reads " + std::to_string(decoder_->NumBits()));
  }
  if (model_.size() == 0) Fail("embed: the model has no Gaussians");
  if (std::none_of(options_.trainable.begin(), options_.trainable.end(),
                   [](bool t) { return t; })) {
    Fail("embed: the mask leaves no trainable parameter group");
  }
  if (!(options_.free_view_fraction >= 0 && options_.free_view_fraction <= 1))
    Fail("embed: free_view_fraction must be in [0, 1]");
  if (options_.free_view_fraction > 0 || options_.fidelity_to_input ||
      options_.owner_reading) {
    input_model_ = model_;
  }
  if (options_.owner_reading && options_.decoder_jitter.enabled()) {
    Fail("embed: the owner's reading takes no decoder jitter");
  }
  if (!(options_.blind.weight >= 0) || !(options_.blind.margin >= 0)) {
    Fail("embed: the blind term's weight and margin must be >= 0");
  }
  if (options_.blind.weight > 0 && !options_.owner_reading) {
    Fail(
        "embed: a blind term goes beside the owner's reading (--reading "
        "both)");
  }
  try {
    CheckFidelityBudget(options_.budget);
  } catch (const std::invalid_argument& e) {
    Fail(std::string("embed: ") + e.what());
  }
  if (options_.budget.enabled() && !(options_.blind.weight > 0)) {
    Fail(
        "embed: a PSNR target steers the blind term: give --reading both "
        "with --blind_weight > 0");
  }
  blind_ = options_.blind;
  if (!(options_.mse_weight >= 0)) Fail("embed: mse_weight must be >= 0");
  if (!(options_.masking >= 0)) Fail("embed: masking must be >= 0");
  if (options_.masking > 0 && options_.mse_weight <= 0) {
    Fail("embed: masking weights the MSE term: give mse_weight > 0");
  }
  if (options_.free_view_neighbors < 0) {
    Fail("embed: free_view_neighbors must be >= 0");
  }
  if (!(options_.margin >= 0)) Fail("embed: margin must be >= 0");
  if (options_.jpeg_quality < 0 || options_.jpeg_quality > 100 ||
      !(options_.jpeg_fraction >= 0 && options_.jpeg_fraction <= 1)) {
    Fail(
        "embed: the JPEG layer needs a quality in 1-100 and a fraction in "
        "[0, 1]");
  }
  if (options_.jpeg_quality > 0 && options_.decoder_jitter.enabled()) {
    Fail("embed: the JPEG layer and decoder jitter do not combine");
  }
  CheckDecoderJitter(options_.decoder_jitter);
  if (options_.free_view_neighbors > 0) FindNeighbors();
  if (options_.hard_views < 0 ||
      !(options_.hard_view_fraction >= 0 && options_.hard_view_fraction <= 1)) {
    Fail("embed: hard_views must be >= 0 and hard_view_fraction in [0, 1]");
  }
  if (options_.hard_views > 0) {
    if (options_.free_view_fraction <= 0) {
      Fail(
          "embed: hard viewpoints replay free-view iterations: give "
          "free_view_fraction > 0");
    }
    pool_ = std::make_unique<ViewpointPool>(
        SampleViewpointsBetween(views_, train_views_, options_.hard_views,
                                options_.seed ^ 0x5851f42d4c957f2dull));
  }
  targets_.assign(message_.begin(), message_.end());
  if (options_.choose_distortions) {
    choice_ = std::make_unique<DistortionChoice>(options_.distortions);
    sampler_ = std::make_unique<DistortionSampler>(choice_->Simulated());
  } else if (!options_.distortions.empty()) {
    sampler_ = std::make_unique<DistortionSampler>(options_.distortions);
  }
  // Density control sets every group of the Gaussians it adds (and prunes
  // frozen ones), which breaks the promise of a partial mask that frozen
  // groups stay bit-identical: refused rather than silently turned off.
  const bool all_trainable =
      std::all_of(options_.trainable.begin(), options_.trainable.end(),
                  [](bool t) { return t; });
  if (options_.densify && !all_trainable) {
    Fail(
        "embed: density control needs every parameter group trainable (a "
        "partial mask keeps the frozen groups bit-identical); turn density "
        "control off");
  }
  density_options_ = options_.density;
  density_options_.seed = options_.seed ^ 0x9e3779b97f4a7c15ull;
  if (options_.densify) {
    strategy_ = MakeInriaDensityStrategy(density_options_, scene_extent_);
  } else {
    strategy_ = MakeFixedDensityStrategy();
  }
  adam_.Init(model_);
  for (int g = 0; g < kNumParamGroups; ++g) {
    adam_.SetGroupEnabled(static_cast<ParamGroup>(g), options_.trainable[g]);
  }
  strategy_->Init(model_);
  origin_.resize(model_.size());
  for (size_t i = 0; i < origin_.size(); ++i) origin_[i] = int64_t(i);
  // On a backend that keeps the model on the device, its step runs there
  // (host_step_reason_ says which option kept it on the host).
  if (DeviceEmbeddingStepFactory make =
          DeviceEmbeddingStepFor(*rasterizer_, *decoder_, options_,
                                 scene_extent_, targets_, &host_step_reason_)) {
    UseDeviceStep(make);
  }
}

Embedder::~Embedder() = default;

void Embedder::UseDeviceStep(const DeviceEmbeddingStepFactory& make) {
  SyncToHost();
  if (device_density_) {
    // The outgoing step's density state moves to the next owner.
    strategy_->Init(model_);
    strategy_->LoadState(device_->SaveDensityState());
  }
  device_ = make(&model_, &adam_);
  device_density_ = false;
  if (device_ && options_.blind.weight > 0) {
    Fail(
        "embed: --reading both runs on the CPU only (the CUDA step has no "
        "blind term yet): give --device cpu");
  }
  if (device_ && options_.densify) {
    device_->TakeDensityControl(density_options_, scene_extent_,
                                strategy_->SaveState());
    device_density_ = true;
  }
}

std::string Embedder::RunSignature() const {
  nlohmann::json j;
  j["iterations"] = options_.iterations;
  j["seed"] = options_.seed;
  j["gamma"] = options_.gamma;
  j["beta"] = options_.beta;
  j["trainable"] = options_.trainable;
  std::string layers;
  for (const auto& spec : options_.distortions) layers += ToString(spec) + ",";
  j["distortions"] = layers;
  if (options_.choose_distortions) {
    // Reviewed at each check: the period is part of the run.
    j["choose_distortions"] = options_.check_every;
  }
  j["crop_size"] = options_.crop_size;
  if (options_.free_view_fraction > 0)
    j["free_view_fraction"] = options_.free_view_fraction;
  if (options_.free_view_neighbors > 0)
    j["free_view_neighbors"] = options_.free_view_neighbors;
  if (options_.decoder_jitter.enabled()) {
    const DecoderJitterOptions& jitter = options_.decoder_jitter;
    j["decoder_jitter"] = {jitter.max_shift, jitter.min_scale,
                           jitter.max_scale};
  }
  if (options_.margin > 0) j["margin"] = options_.margin;
  if (options_.fidelity_to_input) j["fidelity_to_input"] = true;
  if (options_.owner_reading) j["owner_reading"] = true;
  if (options_.blind.weight > 0) {
    j["blind_weight"] = options_.blind.weight;
    j["blind_margin"] = options_.blind.margin;
  }
  if (options_.budget.enabled()) {
    // What the weight is steered by: the target, the step, the bounds, and
    // the checks (when and where they read).
    j["target_psnr"] = {options_.budget.target_db,
                        options_.budget.db_per_doubling,
                        options_.budget.min_weight,
                        options_.budget.max_weight,
                        options_.check_every,
                        options_.check_views.size(),
                        options_.check_free_views.size()};
  }
  if (options_.adam.feature_lr != AdamOptions().feature_lr) {
    j["feature_lr"] = options_.adam.feature_lr;
  }
  if (options_.mse_weight > 0) j["mse_weight"] = options_.mse_weight;
  if (options_.masking > 0) j["masking"] = options_.masking;
  if (options_.jpeg_quality > 0 && options_.jpeg_fraction > 0) {
    // "reference": the owner's reference goes through the JPEG too (a run
    // from before that took it plain must not resume under the new term).
    j["jpeg_layer"] = {options_.jpeg_quality, options_.jpeg_fraction,
                       "reference"};
  }
  if (options_.hard_views > 0) {
    // The pool is rescored every check_every iterations: part of the run.
    j["hard_views"] = {options_.hard_views, options_.hard_view_fraction,
                       options_.check_every};
  }
  j["densify"] = options_.densify;
  j["message"] = BitsToString(message_);
  j["train_views"] = train_views_.size();
  return j.dump();
}

size_t Embedder::NextView() {
  return train_views_[rng_() % train_views_.size()];
}

void Embedder::FindNeighbors() {
  neighbors_.assign(views_.NumViews(), {});
  for (size_t v : train_views_) {
    const Eigen::Vector3d centre = views_.Camera(v).Center();
    std::vector<std::pair<double, size_t>> by_distance;
    for (size_t u : train_views_) {
      if (u == v) continue;
      by_distance.emplace_back((views_.Camera(u).Center() - centre).norm(), u);
    }
    const size_t k =
        std::min<size_t>(options_.free_view_neighbors, by_distance.size());
    std::partial_sort(by_distance.begin(), by_distance.begin() + k,
                      by_distance.end());
    for (size_t i = 0; i < k; ++i) {
      neighbors_[v].push_back(by_distance[i].second);
    }
  }
}

std::shared_ptr<const ImageRGB> Embedder::RenderInput(
    const RenderCamera& camera) {
  RenderOptions options;
  options.background = options_.background;
  auto target = std::make_shared<ImageRGB>();
  rasterizer_->Forward(input_model_, camera, options, target.get(), nullptr);
  // Renders may leave [0, 1]; a photo cannot.
  for (float& v : target->data) v = std::clamp(v, 0.f, 1.f);
  return target;
}

std::shared_ptr<const ImageRGB> Embedder::InputRender(size_t view) {
  if (input_renders_.empty()) input_renders_.resize(views_.NumViews());
  if (!input_renders_[view]) {
    input_renders_[view] = RenderInput(views_.Camera(view));
  }
  return input_renders_[view];
}

LossTerms Embedder::ImageLoss(const ImageRGB& rendered, const ImageRGB& truth,
                              ImageRGB* grad) {
  if (options_.mse_weight <= 0) return loss_.Evaluate(rendered, truth, grad);
  CheckImageSize(rendered.width, rendered.height, truth);
  LossTerms terms;
  const size_t n = rendered.data.size();
  grad->width = rendered.width;
  grad->height = rendered.height;
  grad->data.resize(n);
  double sum_sq = 0, sum_abs = 0;
  const float scale = float(2 * options_.mse_weight / double(n));
  const std::vector<float> weights =
      options_.masking > 0 ? TextureMaskingWeights(truth, options_.masking)
                           : std::vector<float>();
  for (size_t i = 0; i < n; ++i) {
    const float d = rendered.data[i] - truth.data[i];
    const float w = weights.empty() ? 1.f : weights[i / 3];
    sum_sq += double(w) * d * d;
    sum_abs += std::abs(d);
    grad->data[i] = scale * w * d;
  }
  terms.l1 = sum_abs / double(n);
  terms.total = options_.mse_weight * sum_sq / double(n);
  return terms;
}

std::shared_ptr<const std::vector<float>> Embedder::ReferenceLogits(
    const IterationPlan& plan) {
  // The decoded patch in frame pixels: a cropped render is all crop.
  const PixelRect patch =
      plan.render_options.rect.empty() ? plan.decoder_crop : plan.crop;
  if (plan.pool_view >= 0 && patch.empty() && !plan.jpeg) {
    return PoolReferenceLogits(plan.pool_view);
  }
  // Through JPEG the reader's reference goes through the same JPEG (detect
  // compresses the raw render as the suspect image was): so does this one.
  auto& cache = plan.jpeg ? jpeg_reference_logits_ : reference_logits_;
  const bool cacheable = !plan.free_view && patch.empty();
  if (cacheable) {
    if (cache.empty()) cache.resize(views_.NumViews());
    if (cache[plan.view]) return cache[plan.view];
  }
  const std::shared_ptr<const ImageRGB> image =
      plan.free_view ? plan.truth : InputRender(plan.view);
  ImageRGB region;
  if (!patch.empty()) CropImage(*image, patch, &region);
  if (plan.jpeg) {
    region = ApplyImageAttack(
        {ImageAttackKind::kJpeg, double(options_.jpeg_quality)},
        patch.empty() ? *image : region);
  }
  auto logits = std::make_shared<const std::vector<float>>(
      decoder_->Logits(patch.empty() && !plan.jpeg ? *image : region));
  if (cacheable) cache[plan.view] = logits;
  return logits;
}

void Embedder::PlanFreeView(IterationPlan* plan) {
  plan->free_view = true;
  if (pool_ && std::uniform_real_distribution<double>(0, 1)(rng_) <
                   options_.hard_view_fraction) {
    const int k = pool_->Sample(&rng_);
    if (k >= 0) {
      plan->pool_view = k;
      plan->camera = pool_->camera(k);
      plan->truth = PoolTarget(k);
      return;
    }
  }
  const std::vector<size_t>* near =
      neighbors_.empty() ? nullptr : &neighbors_[plan->view];
  const size_t other =
      near && !near->empty() ? (*near)[rng_() % near->size()] : NextView();
  const double t = std::uniform_real_distribution<double>(0, 1)(rng_);
  plan->camera = InterpolateCameras(plan->camera, views_.Camera(other), t);
  plan->truth = RenderInput(plan->camera);
}

PixelRect RandomCrop(int crop_size, int width, int height,
                     std::mt19937_64* rng) {
  PixelRect rect;
  rect.width = std::min(crop_size, width);
  rect.height = std::min(crop_size, height);
  rect.x0 = static_cast<int>((*rng)() % (width - rect.width + 1));
  rect.y0 = static_cast<int>((*rng)() % (height - rect.height + 1));
  return rect;
}

int AutoCropSize(int64_t max_frame_pixels) {
  return max_frame_pixels > kAutoCropMaxFramePixels ? kAutoCropSide : 0;
}

PixelRect Embedder::SampleRect(int width, int height) {
  if (options_.crop_size <= 0) return PixelRect{0, 0, width, height};
  return RandomCrop(options_.crop_size, width, height, &rng_);
}

EmbedStepStats Embedder::Step() {
  const int64_t it = iteration_ + 1;
  EmbedStepStats stats;
  stats.iteration = it;
  adam_.SetIteration(it);
  IterationPlan plan;
  plan.view = NextView();
  plan.camera = views_.Camera(plan.view);
  if (options_.free_view_fraction > 0 &&
      std::uniform_real_distribution<double>(0, 1)(rng_) <
          options_.free_view_fraction) {
    PlanFreeView(&plan);
  } else if (options_.fidelity_to_input) {
    plan.truth = InputRender(plan.view);
  } else {
    plan.truth = views_.Image(plan.view);
  }
  plan.crop = SampleRect(plan.camera.width, plan.camera.height);
  plan.layer = sampler_ ? &sampler_->Sample(rng_) : nullptr;
  stats.distortion = plan.layer ? ToString(plan.layer->spec()) : "none";
  plan.render_options.background = options_.background;
  if (!options_.full_frame_image_loss) plan.render_options.rect = plan.crop;
  // The decoder reads the crop; a cropped render is all crop.
  if (plan.render_options.rect.empty() && options_.crop_size > 0) {
    plan.decoder_crop = plan.crop;
  }
  if (options_.decoder_jitter.enabled()) {
    const int w =
        plan.decoder_crop.empty() ? plan.crop.width : plan.decoder_crop.width;
    const int h =
        plan.decoder_crop.empty() ? plan.crop.height : plan.decoder_crop.height;
    plan.jitter = SampleJitter(options_.decoder_jitter, w, h, &rng_);
  }
  if (options_.jpeg_quality > 0 && options_.jpeg_fraction > 0) {
    plan.jpeg = std::uniform_real_distribution<double>(0, 1)(rng_) <
                options_.jpeg_fraction;
  }
  if (options_.owner_reading) plan.reference_logits = ReferenceLogits(plan);

  const DensityEvent event = device_ ? DeviceIteration(it, plan, &stats)
                                     : HostIteration(it, plan, &stats);
  const size_t num_gaussians =
      device_ ? device_->NumGaussians() : model_.size();
  if (num_gaussians == 0) {
    Fail("embed stopped at iteration " + std::to_string(it) +
         ": density control pruned every Gaussian");
  }
  if (event.densified) {
    std::vector<int64_t> origin(event.parent.size());
    for (size_t i = 0; i < origin.size(); ++i) {
      origin[i] = event.parent[i] < 0 ? -1 : origin_[event.parent[i]];
    }
    origin_ = std::move(origin);
  }
  total_timings_.Add(stats.timings);
  stats.num_gaussians = num_gaussians;
  iteration_ = it;
  if (pool_ && options_.check_every > 0 && it % options_.check_every == 0) {
    ScorePool();
  }
  return stats;
}

void Embedder::CheckLossFinite(int64_t it, const IterationPlan& plan,
                               const EmbedStepStats& stats) const {
  if (!std::isfinite(stats.total)) {
    Fail("embed stopped at iteration " + std::to_string(it) +
         ": the loss is not finite on view " + views_.Name(plan.view));
  }
}

DensityEvent Embedder::HostIteration(int64_t it, const IterationPlan& plan,
                                     EmbedStepStats* stats) {
  // N(Θ): the identity renders the model itself (no copy, no scatter).
  auto t0 = Clock::now();
  const bool distort = plan.layer && !plan.layer->IsIdentity();
  if (distort) plan.layer->Apply(model_, rng_, &distorted_, &source_);
  const GaussianModel& rendered_model = distort ? distorted_ : model_;

  auto t1 = Clock::now();
  std::unique_ptr<RenderContext> context;
  rasterizer_->Forward(rendered_model, plan.camera, plan.render_options,
                       &render_, &context);
  auto t2 = Clock::now();
  const bool cropped = !plan.render_options.rect.empty();
  if (cropped) CropImage(*plan.truth, plan.crop, &truth_crop_);
  stats->image =
      ImageLoss(render_, cropped ? truth_crop_ : *plan.truth, &grad_image_);
  auto t3 = Clock::now();

  // Message term on the crop: BCE(m, D(crop)) and its image gradient.
  if (options_.decoder_jitter.enabled()) {
    stats->bce = JitteredMessageLoss(plan, stats);
  } else if (plan.jpeg) {
    stats->bce = JpegMessageLoss(plan, stats);
  } else {
    stats->bce =
        AddMessageLoss(*decoder_, render_, plan.decoder_crop, targets_,
                       options_.gamma, &grad_image_, &stats->bit_errors,
                       options_.margin, plan.reference_logits.get(), blind_);
  }
  stats->total = stats->image.total + options_.gamma * stats->bce;
  auto t4 = Clock::now();
  CheckLossFinite(it, plan, *stats);

  if (distort) {
    rasterizer_->Backward(rendered_model, *context, grad_image_,
                          &distorted_grads_);
    ScatterGradients(distorted_grads_, source_, model_.size(),
                     model_.sh_rest_stride(), &grads_);
  } else {
    rasterizer_->Backward(model_, *context, grad_image_, &grads_);
  }
  context.reset();
  auto t5 = Clock::now();

  const std::vector<float>* radii = nullptr;
  if (strategy_->WantsRadii(it)) {
    ComputeScreenRadii(model_, plan.camera, grads_.visible, &radii_);
    radii = &radii_;
  }
  DensityEvent event =
      strategy_->PostBackward(it, grads_, radii, &model_, &adam_);
  auto t6 = Clock::now();
  if (!event.densified && model_.size() > 0) adam_.Step(grads_, &model_);
  auto t7 = Clock::now();

  EmbedTimings& t = stats->timings;
  t.distortion = Seconds(t0, t1);
  t.render = Seconds(t1, t2);
  t.image_loss = Seconds(t2, t3);
  t.decoder = Seconds(t3, t4);
  t.backward = Seconds(t4, t5);
  t.density = Seconds(t5, t6);
  t.adam = Seconds(t6, t7);
  return event;
}

double Embedder::JpegMessageLoss(const IterationPlan& plan,
                                 EmbedStepStats* stats) {
  return AddJpegMessageLoss(*decoder_, render_, plan.decoder_crop,
                            options_.jpeg_quality, targets_, options_.gamma,
                            &grad_image_, &stats->bit_errors, options_.margin,
                            plan.reference_logits.get(), blind_);
}

double Embedder::JitteredMessageLoss(const IterationPlan& plan,
                                     EmbedStepStats* stats) {
  const PixelRect crop = plan.decoder_crop.empty()
                             ? PixelRect{0, 0, render_.width, render_.height}
                             : plan.decoder_crop;
  if (!plan.decoder_crop.empty()) CropImage(render_, crop, &decoder_region_);
  const ImageRGB& region =
      plan.decoder_crop.empty() ? render_ : decoder_region_;
  JitterForward(region, plan.jitter, &jittered_);
  grad_jittered_ = ImageRGB(jittered_.width, jittered_.height);
  const double bce = AddMessageLoss(*decoder_, jittered_, PixelRect{}, targets_,
                                    options_.gamma, &grad_jittered_,
                                    &stats->bit_errors, options_.margin);
  ImageRGB grad_region(region.width, region.height);
  JitterAdjoint(grad_jittered_, plan.jitter, &grad_region);
  AddPatch(grad_region, crop, 1.f, &grad_image_);
  return bce;
}

DensityEvent Embedder::DeviceIteration(int64_t it, const IterationPlan& plan,
                                       EmbedStepStats* stats) {
  DeviceEmbedView view;
  view.camera = plan.camera;
  view.options = plan.render_options;
  const bool cropped = !plan.render_options.rect.empty();
  if (cropped) CropImage(*plan.truth, plan.crop, &truth_crop_);
  view.truth = cropped ? &truth_crop_ : plan.truth.get();
  view.decoder_crop = plan.decoder_crop;
  view.layer = plan.layer;
  view.reference_logits = plan.reference_logits.get();
  const DeviceEmbedLoss loss = device_->Forward(view, rng_);
  stats->image = loss.image;
  stats->bce = loss.bce;
  stats->bit_errors = loss.bit_errors;
  stats->total = stats->image.total + options_.gamma * stats->bce;
  CheckLossFinite(it, plan, *stats);
  EmbedTimings& t = stats->timings;
  t.distortion = loss.distortion_s;
  t.render = loss.render_s;
  t.image_loss = loss.image_loss_s;
  t.decoder = loss.decoder_s;
  return device_->BackwardAndUpdate(it, &t.backward, &t.density, &t.adam);
}

void Embedder::SyncToHost() const {
  if (device_) {
    device_->PullModel();
    device_->PullAdam();
  }
}

const GaussianModel& Embedder::model() const {
  if (device_) device_->PullModel();
  return model_;
}

void Embedder::RenderCurrent(const RenderCamera& camera, ImageRGB* image) {
  RenderOptions render_options;
  render_options.background = options_.background;
  // The device path renders its resident model (no model download).
  if (device_) {
    device_->Render(camera, render_options, image);
  } else {
    rasterizer_->Forward(model_, camera, render_options, image, nullptr);
  }
  for (float& v : image->data) v = std::clamp(v, 0.f, 1.f);
}

std::shared_ptr<const ImageRGB> Embedder::PoolTarget(size_t k) {
  if (pool_targets_.empty()) pool_targets_.resize(pool_->size());
  if (!pool_targets_[k]) pool_targets_[k] = RenderInput(pool_->camera(k));
  return pool_targets_[k];
}

std::shared_ptr<const std::vector<float>> Embedder::PoolReferenceLogits(
    size_t k) {
  if (pool_logits_.empty()) pool_logits_.resize(pool_->size());
  if (!pool_logits_[k]) {
    pool_logits_[k] = std::make_shared<const std::vector<float>>(
        decoder_->Logits(*PoolTarget(k)));
  }
  return pool_logits_[k];
}

void Embedder::ScorePool() {
  // Short of the margin the message term pushes towards (1 without one, so
  // that bits barely past zero still count).
  const double margin = options_.margin > 0 ? options_.margin : 1.0;
  ImageRGB image;
  for (size_t k = 0; k < pool_->size(); ++k) {
    RenderCurrent(pool_->camera(k), &image);
    std::vector<float> logits = decoder_->Logits(image);
    if (options_.owner_reading) {
      SubtractReference(*PoolReferenceLogits(k), message_, &logits);
    }
    pool_->SetDeficit(k, MarginDeficit(logits, message_, margin));
  }
}

std::vector<RenderCamera> Embedder::CheckCameras(
    const std::vector<size_t>& views) const {
  std::vector<RenderCamera> cameras;
  for (size_t view : views) cameras.push_back(views_.Camera(view));
  cameras.insert(cameras.end(), options_.check_free_views.begin(),
                 options_.check_free_views.end());
  return cameras;
}

const std::vector<std::vector<float>>& Embedder::CheckReference(
    const std::vector<size_t>& views) {
  // The input model and the decoder are fixed: one reading per view set.
  if (!options_.owner_reading ||
      (check_reference_views_ == views && !check_reference_.empty())) {
    return check_reference_;
  }
  check_reference_.clear();
  check_reference_views_ = views;
  // The input's renders are CheckInputs' (rendered once for both).
  for (const auto& input : CheckInputs(views)) {
    check_reference_.push_back(decoder_->Logits(*input));
  }
  return check_reference_;
}

const std::vector<std::shared_ptr<const ImageRGB>>& Embedder::CheckInputs(
    const std::vector<size_t>& views) {
  // The input model is fixed: one set of renders per view set.
  if (input_model_.size() == 0 ||
      (check_inputs_views_ == views && !check_inputs_.empty())) {
    return check_inputs_;
  }
  check_inputs_.clear();
  check_inputs_views_ = views;
  for (const RenderCamera& camera : CheckCameras(views)) {
    check_inputs_.push_back(RenderInput(camera));
  }
  return check_inputs_;
}

std::vector<std::vector<float>> Embedder::ReadCameras(
    const GaussianModel* model, const std::vector<RenderCamera>& cameras,
    const std::vector<std::vector<float>>& reference,
    const std::vector<std::shared_ptr<const ImageRGB>>* truths, double* psnr,
    const std::vector<std::shared_ptr<const ImageRGB>>* inputs,
    double* psnr_vs_input) {
  std::vector<std::vector<float>> logits(cameras.size());
  ImageRGB image;
  RenderOptions render_options;
  render_options.background = options_.background;
  for (size_t k = 0; k < cameras.size(); ++k) {
    if (model) {
      rasterizer_->Forward(*model, cameras[k], render_options, &image, nullptr);
      for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    } else {
      RenderCurrent(cameras[k], &image);
    }
    logits[k] = decoder_->Logits(image);
    if (options_.owner_reading) {
      SubtractReference(reference[k], message_, &logits[k]);
    }
    if (truths && k < truths->size()) {
      *psnr += Psnr(image, *(*truths)[k]) / truths->size();
    }
    if (inputs && k < inputs->size()) {
      // A view the change leaves untouched reads +inf: capped, so that one
      // such view cannot carry the mean (and the budget) with it.
      *psnr_vs_input +=
          std::min(Psnr(image, *(*inputs)[k]), kMaxPsnrDb) / inputs->size();
    }
  }
  return logits;
}

bool Embedder::ReviewDistortions(const CheckResult& check) {
  const std::vector<std::vector<float>>& plain = check.logits;
  if (!DistortionChoice::Ready(plain, options_.check_views.size(), message_,
                               options_.margin)) {
    return false;
  }
  const std::vector<RenderCamera> cameras = CheckCameras(options_.check_views);
  const std::vector<std::vector<float>>& reference =
      CheckReference(options_.check_views);
  const GaussianModel& current = model();
  bool turned_on = false;
  for (size_t k = 0; k < choice_->candidates().size(); ++k) {
    // Draws from the seed, the iteration and the candidate (the iterations'
    // own random stream stays untouched).
    std::seed_seq seq{options_.seed, uint64_t(iteration_), uint64_t(k)};
    std::mt19937_64 rng(seq);
    const auto layer = MakeDistortionLayer(choice_->candidates()[k].spec);
    std::vector<std::vector<float>> through;
    for (int draw = 0; draw < kReviewDraws; ++draw) {
      layer->Apply(current, rng, &distorted_, &source_);
      for (std::vector<float>& logits :
           ReadCameras(&distorted_, cameras, reference)) {
        through.push_back(std::move(logits));
      }
    }
    turned_on |= choice_->Review(k, iteration_, message_, plain, through);
  }
  if (turned_on) {
    sampler_ = std::make_unique<DistortionSampler>(choice_->Simulated());
  }
  return turned_on;
}

CheckResult Embedder::Check(const std::vector<size_t>& views) {
  CheckResult result;
  std::vector<std::shared_ptr<const ImageRGB>> truths;
  for (size_t view : views) truths.push_back(views_.Image(view));
  result.logits =
      ReadCameras(nullptr, CheckCameras(views), CheckReference(views), &truths,
                  &result.psnr, &CheckInputs(views), &result.psnr_vs_input);
  const size_t num_free = result.logits.size() - views.size();
  std::vector<double> sum_logits(message_.size(), 0.0);
  for (size_t k = 0; k < result.logits.size(); ++k) {
    const std::vector<float>& logits = result.logits[k];
    const double ber =
        double(CountBitErrors(logits, message_)) / message_.size();
    result.weakest_margin =
        std::min(result.weakest_margin, WeakestMargin(logits, message_));
    if (k >= views.size()) {
      result.free_mean_ber += ber / num_free;
      continue;
    }
    result.mean_ber += ber / views.size();
    for (size_t i = 0; i < logits.size(); ++i) sum_logits[i] += logits[i];
  }
  if (!views.empty()) {
    const std::vector<float> aggregate(sum_logits.begin(), sum_logits.end());
    result.aggregate_ber =
        double(CountBitErrors(aggregate, message_)) / message_.size();
  }
  return result;
}

bool Embedder::Run() {
  std::unique_ptr<ProgressBar> bar;
  if (options_.show_progress) {
    bar =
        std::make_unique<ProgressBar>("embed", options_.iterations, iteration_);
  }
  RunningAverage loss(0.9), ber(0.95);
  CheckResult last_check;
  bool checked = false, stopped_early = false, read_past_margin = false;
  while (iteration_ < options_.iterations) {
    const EmbedStepStats stats = Step();
    loss.Add(stats.total);
    ber.Add(double(stats.bit_errors) / message_.size());
    const int64_t it = stats.iteration;
    if (options_.check_every > 0 && it % options_.check_every == 0 &&
        !options_.check_views.empty()) {
      const auto check_start = Clock::now();
      last_check = Check(options_.check_views);
      checked = true;
      zero_ber_checks_ =
          last_check.mean_ber == 0 && last_check.free_mean_ber == 0
              ? zero_ber_checks_ + 1
              : 0;
      blind_.weight = NextBlindWeight(options_.budget, blind_.weight,
                                      last_check.psnr_vs_input);
      read_past_margin = options_.stop_margin > 0 &&
                         last_check.weakest_margin >= options_.stop_margin;
      // A layer turned on now has iterations to come before any stop.
      if (choice_ && ReviewDistortions(last_check)) {
        zero_ber_checks_ = 0;
        read_past_margin = false;
        if (bar) bar->Print("embed: distortion layers " + choice_->Summary());
      }
      const double seconds = Seconds(check_start, Clock::now());
      check_seconds_ += seconds;
      ++num_checks_;
      if (bar) {
        // A check costs tens of steps: priced apart, once per check to come.
        bar->AddSideWork("check", seconds,
                         options_.iterations / options_.check_every -
                             it / options_.check_every);
      }
    }
    if (options_.checkpoint_every > 0 && it % options_.checkpoint_every == 0 &&
        !options_.checkpoint_path.empty()) {
      SaveCheckpoint(options_.checkpoint_path);
    }
    if (bar) {
      char status[160];
      std::snprintf(status, sizeof(status),
                    "loss %.4f  BER %.1f%%  %zu Gaussians", loss.value(),
                    100 * ber.value(), stats.num_gaussians);
      std::string line = status;
      if (checked) {
        std::snprintf(status, sizeof(status), "  check BER %.1f%% PSNR %.2f",
                      100 * last_check.mean_ber, last_check.psnr);
        if (!options_.check_free_views.empty()) {
          line += status;
          std::snprintf(status, sizeof(status), " free %.1f%%",
                        100 * last_check.free_mean_ber);
        }
        line += status;
        if (options_.budget.enabled()) {
          std::snprintf(status, sizeof(status), "  vs input %.2f blind w %.3g",
                        last_check.psnr_vs_input, blind_.weight);
          line += status;
        }
      }
      if (pool_) {
        std::snprintf(status, sizeof(status), "  hard %zu/%zu",
                      pool_->NumShort(), pool_->size());
        line += status;
      }
      bar->Update(it, line);
    }
    if ((options_.patience > 0 && zero_ber_checks_ >= options_.patience) ||
        read_past_margin) {
      stopped_early = true;
      break;
    }
  }
  if (bar) {
    char why[200];
    if (read_past_margin) {
      std::snprintf(why, sizeof(why),
                    "stopped at iteration %lld: every check view and free "
                    "viewpoint reads all %zu bits at least %.2f past zero "
                    "(weakest %.2f)",
                    static_cast<long long>(iteration_), message_.size(),
                    options_.stop_margin, last_check.weakest_margin);
    } else {
      std::snprintf(why, sizeof(why), "%s",
                    stopped_early ? "stopped early: check BER 0" : "done");
    }
    bar->Finish(why);
  }
  return stopped_early;
}

void Embedder::SaveCheckpoint(const std::string& path) const {
  SyncToHost();
  TrainingCheckpoint c;
  c.iteration = iteration_;
  c.active_sh_degree = model_.sh_degree;
  c.model = model_;
  for (int g = 0; g < kNumParamGroups; ++g) {
    c.adam[g] = adam_.state(static_cast<ParamGroup>(g));
  }
  c.adam_rejected = adam_.rejected_total();
  c.density_state =
      device_density_ ? device_->SaveDensityState() : strategy_->SaveState();
  std::ostringstream rng_text;
  rng_text << rng_;
  // The RNG and the descent of each Gaussian from the input, as JSON.
  nlohmann::json extra;
  extra["rng"] = rng_text.str();
  extra["origin"] = origin_;
  extra["zero_ber_checks"] = zero_ber_checks_;
  extra["blind_weight"] = blind_.weight;
  if (pool_) extra["pool_deficits"] = pool_->deficits();
  if (choice_) extra["distortions_since"] = choice_->State();
  c.rng_state = extra.dump();
  c.run_signature = RunSignature();
  WriteCheckpoint(path, c);
}

void Embedder::Resume(const std::string& path) {
  TrainingCheckpoint c = ReadCheckpoint(path);
  if (c.run_signature != RunSignature()) {
    const std::string differences =
        SignatureDifferences(c.run_signature, RunSignature());
    FailAt(path, "checkpoint was written by an embed run with other options" +
                     (differences.empty() ? "" : " (" + differences + ")"));
  }
  if (c.model.sh_degree != model_.sh_degree) {
    FailAt(path, "checkpoint SH degree differs from the input model's");
  }
  const auto extra = nlohmann::json::parse(c.rng_state, nullptr, false);
  if (extra.is_discarded() || !extra.contains("rng") ||
      !extra["rng"].is_string() || !extra.contains("origin") ||
      !extra["origin"].is_array()) {
    FailAt(path, "not an embed checkpoint");
  }
  std::vector<int64_t> origin;
  int zero_ber_checks = 0;
  double blind_weight = options_.blind.weight;
  try {
    origin = extra["origin"].get<std::vector<int64_t>>();
    zero_ber_checks = extra.value("zero_ber_checks", 0);
    blind_weight = extra.value("blind_weight", blind_weight);
  } catch (const nlohmann::json::exception&) {
    FailAt(path, "checkpoint embed state has fields of the wrong type");
  }
  // Checked before any state is replaced.
  const bool weight_in_bounds = !options_.budget.enabled() ||
                                (blind_weight >= options_.budget.min_weight &&
                                 blind_weight <= options_.budget.max_weight);
  if (!std::isfinite(blind_weight) || blind_weight < 0 || !weight_in_bounds) {
    FailAt(path, "checkpoint's blind weight is not one this run can steer");
  }
  model_ = std::move(c.model);
  adam_.Init(model_);
  for (int g = 0; g < kNumParamGroups; ++g) {
    AdamGroupState& s = adam_.state(static_cast<ParamGroup>(g));
    if (c.adam[g].exp_avg.size() != s.exp_avg.size()) {
      FailAt(path, "checkpoint optimiser state does not match its model");
    }
    s = std::move(c.adam[g]);
  }
  adam_.set_rejected_total(c.adam_rejected);
  strategy_->Init(model_);
  try {
    strategy_->LoadState(c.density_state);
  } catch (const Error& e) {
    FailAt(path, e.what());
  }
  std::istringstream rng_in(extra["rng"].get<std::string>());
  rng_in >> rng_;
  origin_ = std::move(origin);
  zero_ber_checks_ = zero_ber_checks;
  blind_.weight = blind_weight;
  if (pool_ && extra.contains("pool_deficits")) {
    std::vector<double> deficits;
    try {
      deficits = extra["pool_deficits"].get<std::vector<double>>();
    } catch (const nlohmann::json::exception&) {
      FailAt(path, "checkpoint embed state has fields of the wrong type");
    }
    if (!pool_->RestoreDeficits(deficits)) {
      FailAt(path, "checkpoint's hard-viewpoint pool does not match the run");
    }
  }
  if (choice_) {
    std::vector<int64_t> since;
    try {
      since = extra.value("distortions_since", std::vector<int64_t>{});
    } catch (const nlohmann::json::exception&) {
      FailAt(path, "checkpoint embed state has fields of the wrong type");
    }
    if (!choice_->Restore(since)) {
      FailAt(path,
             "checkpoint's chosen distortion layers do not match the run");
    }
    sampler_ = std::make_unique<DistortionSampler>(choice_->Simulated());
  }
  if (!rng_in || origin_.size() != model_.size()) {
    FailAt(path, "checkpoint state is corrupt");
  }
  iteration_ = c.iteration;
  if (device_) {
    device_->MarkHostEdited();
    if (device_density_) device_->LoadDensityState(c.density_state);
  }
}

}  // namespace watergs
