// The 3DGS training loop (see trainer.h).
#include "gaussian/trainer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "gaussian/backend.h"
#include "gaussian/projection.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"

namespace watergs {
namespace {

using Clock = std::chrono::steady_clock;

// CPU seconds of the whole process (all threads).
double ProcessCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

std::string RngState(const std::mt19937_64& rng) {
  std::ostringstream out;
  out << rng;
  return out.str();
}

size_t GradientBytesPerGaussian(const GaussianModel& model, bool compact_sh) {
  // Parameter gradients (SH ones dense or as colour gradient and view
  // direction), mean2d norms (two), visibility byte.
  const size_t sh_floats = compact_sh ? 6 : 3 + model.sh_rest_stride();
  const size_t floats = 3 + 3 + 4 + 1 + sh_floats;
  return floats * sizeof(float) + 2 * sizeof(float) + 1;
}

}  // namespace

void InMemoryViews::Add(std::string name, const RenderCamera& camera,
                        ImageRGB image) {
  names_.push_back(std::move(name));
  cameras_.push_back(camera);
  images_.push_back(std::make_shared<const ImageRGB>(std::move(image)));
}

EvalResult EvaluateViews(Rasterizer& rasterizer, const GaussianModel& model,
                         const TrainingViews& source,
                         const std::vector<size_t>& views,
                         const std::array<float, 3>& background,
                         int active_sh_degree, std::vector<ImageRGB>* renders) {
  EvalResult result;
  RenderOptions options;
  options.background = background;
  options.active_sh_degree = active_sh_degree;
  ImageRGB image;
  for (size_t view : views) {
    rasterizer.Forward(model, source.Camera(view), options, &image, nullptr);
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    const std::shared_ptr<const ImageRGB> truth = source.Image(view);
    const double psnr = Psnr(image, *truth);
    const double ssim = Ssim(image, *truth);
    result.view_psnr.push_back(psnr);
    result.view_ssim.push_back(ssim);
    result.psnr += psnr;
    result.ssim += ssim;
    result.l1 += L1(image, *truth);
    if (renders) renders->push_back(image);
  }
  result.num_views = views.size();
  if (!views.empty()) {
    result.psnr /= views.size();
    result.ssim /= views.size();
    result.l1 /= views.size();
  }
  return result;
}

Trainer::Trainer(const TrainerOptions& options, const TrainingViews& views,
                 std::vector<size_t> train_views, GaussianModel initial,
                 double scene_extent, std::unique_ptr<Rasterizer> rasterizer,
                 std::unique_ptr<DensityStrategy> strategy)
    : options_(options),
      views_(views),
      train_views_(std::move(train_views)),
      model_(std::move(initial)),
      scene_extent_(scene_extent),
      rasterizer_(std::move(rasterizer)),
      strategy_(std::move(strategy)),
      adam_(options.adam, scene_extent),
      loss_(options.lambda_dssim),
      rng_(options.seed) {
  if (train_views_.empty()) Fail("training: no training views");
  for (size_t v : train_views_) {
    if (v >= views_.NumViews()) Fail("training: view index out of range");
  }
  if (!strategy_) {
    DensityOptions density = options_.density;
    density.seed = options_.seed ^ 0x9e3779b97f4a7c15ull;
    strategy_ = MakeInriaDensityStrategy(density, scene_extent_);
    builtin_density_ = std::make_unique<DensityOptions>(density);
  }
  active_sh_degree_ =
      std::clamp(options_.initial_sh_degree, 0, model_.sh_degree);
  adam_.Init(model_);
  strategy_->Init(model_);
  // Factored SH gradients are exact and save 168 bytes per Gaussian; the
  // 8-bit compact moments read dense ones.
  grads_.compact_sh = !options_.adam.compact_moments;
  // On a backend that keeps the model on the device, its step runs there.
  if (DeviceTrainingStepFactory make = DeviceTrainingStepFor(
          *rasterizer_, options_.adam, scene_extent_, options_.lambda_dssim)) {
    UseDeviceStep(make);
  }
}

Trainer::~Trainer() = default;

void Trainer::UseDeviceStep(const DeviceTrainingStepFactory& make) {
  SyncToHost();
  if (device_density_) {
    // The outgoing step's density state moves to the next owner.
    strategy_->Init(model_);
    strategy_->LoadState(device_->SaveDensityState());
  }
  device_ = make(&model_, &adam_);
  device_density_ = builtin_density_ && device_->TakeDensityControl(
                                            *builtin_density_, scene_extent_,
                                            strategy_->SaveState());
}

// The host model_ and adam_ are a cache of the device state on the GPU path:
// filling them from the const accessors is what `const` promises callers
// (the state they see is the trainer's), so the device step writes them
// through the pointers it was given.
void Trainer::SyncToHost() const {
  if (device_) {
    device_->PullModel();
    device_->PullAdam();
  }
}

const GaussianModel& Trainer::model() const {
  if (device_) device_->PullModel();
  return model_;
}

GaussianModel& Trainer::mutable_model() {
  if (device_) {
    device_->PullModel();
    device_->MarkHostModelEdited();
  }
  return model_;
}

Adam& Trainer::adam() {
  if (device_) {
    device_->PullAdam();
    device_->MarkHostAdamEdited();
  }
  return adam_;
}

std::string Trainer::RunSignature() const {
  nlohmann::json j;
  j["iterations"] = options_.iterations;
  j["seed"] = options_.seed;
  j["sh_degree"] = model_.sh_degree;
  j["background"] = options_.background;
  j["train_views"] = train_views_.size();
  j["lambda_dssim"] = options_.lambda_dssim;
  j["position_lr_max_steps"] = options_.adam.position_lr_max_steps;
  j["compact_moments"] = options_.adam.compact_moments;
  // Only when set, so that checkpoints of runs before the option still match.
  if (options_.adam.half_moments) j["half_moments"] = true;
  // The degree the run starts at (capped by the model's), when not Inria's 0.
  const int initial_sh =
      std::clamp(options_.initial_sh_degree, 0, model_.sh_degree);
  if (initial_sh != 0) j["initial_sh_degree"] = initial_sh;
  // Density schedule, also only when it differs from Inria's (same reason):
  // resuming with another schedule would silently give another model.
  const DensityOptions& d = options_.density;
  const DensityOptions inria;
  if (d.densify_from_iter != inria.densify_from_iter ||
      d.densify_until_iter != inria.densify_until_iter ||
      d.densification_interval != inria.densification_interval ||
      d.opacity_reset_interval != inria.opacity_reset_interval ||
      d.grad_threshold != inria.grad_threshold) {
    j["density"] = {d.densify_from_iter, d.densify_until_iter,
                    d.densification_interval, d.opacity_reset_interval,
                    d.grad_threshold};
  }
  return j.dump();
}

size_t Trainer::NextView() {
  if (view_stack_.empty()) {
    for (size_t i = 0; i < train_views_.size(); ++i) {
      view_stack_.push_back(static_cast<uint32_t>(i));
    }
  }
  // Inria pops a uniformly random entry of the remaining views.
  const size_t pick = rng_() % view_stack_.size();
  const uint32_t view = view_stack_[pick];
  view_stack_.erase(view_stack_.begin() + pick);
  return train_views_[view];
}

namespace {

// Stage times of a step from the wall and CPU clocks read at its six stage
// boundaries, and what density control did.
void FillStepStats(const std::array<Clock::time_point, 6>& wall,
                   const std::array<double, 6>& cpu, const DensityEvent& event,
                   size_t num_gaussians, IterationStats* stats) {
  stats->forward_s = Seconds(wall[0], wall[1]);
  stats->loss_s = Seconds(wall[1], wall[2]);
  stats->backward_s = Seconds(wall[2], wall[3]);
  stats->density_s = Seconds(wall[3], wall[4]);
  stats->adam_s = Seconds(wall[4], wall[5]);
  for (int k = 0; k < 5; ++k) stats->cpu_s[k] = cpu[k + 1] - cpu[k];
  stats->num_gaussians = num_gaussians;
  stats->cloned = event.cloned;
  stats->split = event.split;
  stats->pruned = event.pruned;
}

}  // namespace

IterationStats Trainer::Step() {
  const int64_t it = iteration_ + 1;
  IterationStats stats;
  stats.iteration = it;
  adam_.SetIteration(it);
  if (options_.sh_increase_interval > 0 &&
      it % options_.sh_increase_interval == 0 &&
      active_sh_degree_ < model_.sh_degree) {
    ++active_sh_degree_;
  }
  const size_t view = NextView();
  const RenderCamera camera = views_.Camera(view);
  const std::shared_ptr<const ImageRGB> truth = views_.Image(view);

  RenderOptions render_options;
  render_options.background = options_.background;
  render_options.active_sh_degree = active_sh_degree_;
  if (device_) return StepOnDevice(it, view, camera, render_options, *truth);
  auto t0 = Clock::now();
  const double c0 = ProcessCpuSeconds();
  std::unique_ptr<RenderContext> context;
  rasterizer_->Forward(model_, camera, render_options, &render_, &context);
  auto t1 = Clock::now();
  const double c1 = ProcessCpuSeconds();
  stats.loss = loss_.Evaluate(render_, *truth, &grad_image_);
  auto t2 = Clock::now();
  const double c2 = ProcessCpuSeconds();
  if (!std::isfinite(stats.loss.total)) {
    FailNonFiniteLoss(it, stats.loss.total, view);
  }
  rasterizer_->Backward(model_, *context, grad_image_, &grads_);
  context.reset();
  auto t3 = Clock::now();
  const double c3 = ProcessCpuSeconds();
  const std::vector<float>* radii = nullptr;
  if (strategy_->WantsRadii(it)) {
    ComputeScreenRadii(model_, camera, grads_.visible, &radii_);
    radii = &radii_;
  }
  // The last iteration's model is the one written and scored, so, as Inria
  // saves before densifying, it is not densified, pruned or reset.
  const DensityEvent event =
      it < options_.iterations
          ? strategy_->PostBackward(it, grads_, radii, &model_, &adam_)
          : DensityEvent{};
  if (model_.size() == 0) FailAllPruned(it);
  auto t4 = Clock::now();
  const double c4 = ProcessCpuSeconds();
  // Inria: tensors replaced by densification or an opacity reset have no
  // gradient at this step, and the last iteration takes no step.
  if (it < options_.iterations && !event.densified) {
    const bool opacity_enabled = adam_.GroupEnabled(ParamGroup::kOpacity);
    if (event.opacity_reset) adam_.SetGroupEnabled(ParamGroup::kOpacity, false);
    adam_.Step(grads_, &model_);
    adam_.SetGroupEnabled(ParamGroup::kOpacity, opacity_enabled);
  }
  auto t5 = Clock::now();
  const double c5 = ProcessCpuSeconds();
  FillStepStats({t0, t1, t2, t3, t4, t5}, {c0, c1, c2, c3, c4, c5}, event,
                model_.size(), &stats);
  iteration_ = it;
  elapsed_seconds_ += Seconds(t0, t5);
  return stats;
}

void Trainer::FailNonFiniteLoss(int64_t it, double loss, size_t view) {
  FlushLog();
  std::string kept = last_checkpoint_.empty()
                         ? "no checkpoint was written (use "
                           "--checkpoint_every)"
                         : "the last checkpoint is " + last_checkpoint_ +
                               " (iteration " +
                               std::to_string(last_checkpoint_iteration_) + ")";
  Fail("training stopped at iteration " + std::to_string(it) +
       ": the loss is not finite (" + std::to_string(loss) + ") on view " +
       views_.Name(view) + "; " + kept);
}

void Trainer::FailAllPruned(int64_t it) {
  FlushLog();
  Fail("training stopped at iteration " + std::to_string(it) +
       ": density control pruned every Gaussian (all nearly transparent "
       "or too large)");
}

// Step on the device: the same stages and rules as the host path. With the
// built-in Inria strategy the device step runs density control itself
// (DensityStep): nothing per Gaussian crosses the bus, and the trainer reads
// only the event and the Gaussian count. A strategy passed in runs on the
// host (HostDensityStep): on iterations where it only accumulates
// statistics it gets this view's visibility and NDC gradient norms (and
// radii) and a host model of the right size; where it may change the model
// (MayChangeModel: for Inria's ADC the densification iterations, every 100,
// and opacity resets) the model and Adam moments come down first and go
// back up after. That round trip is ~710 bytes per Gaussian each way at SH
// degree 3 (59 parameters and 2 x 59 moments): ~0.7 GB each way at 1M
// Gaussians, ~100 ms with the host densification (estimated from PCIe
// rates, not measured) every 100 iterations: ~1 ms per iteration amortised.
// Other iterations move 5 bytes per Gaussian down (9 with radii).
IterationStats Trainer::StepOnDevice(int64_t it, size_t view,
                                     const RenderCamera& camera,
                                     const RenderOptions& render_options,
                                     const ImageRGB& truth) {
  IterationStats stats;
  stats.iteration = it;
  auto t0 = Clock::now();
  const double c0 = ProcessCpuSeconds();
  device_->Forward(camera, render_options, truth);
  device_->Synchronize();
  auto t1 = Clock::now();
  const double c1 = ProcessCpuSeconds();
  stats.loss = device_->Loss();
  auto t2 = Clock::now();
  const double c2 = ProcessCpuSeconds();
  if (!std::isfinite(stats.loss.total)) {
    FailNonFiniteLoss(it, stats.loss.total, view);
  }
  const bool last = it >= options_.iterations;
  // Host strategy only: what it reads comes down.
  const bool host_density = !last && !device_density_;
  const bool wants_radii = host_density && strategy_->WantsRadii(it);
  device_->Backward(
      host_density && strategy_->ReadsGradients(it) ? &grads_ : nullptr,
      wants_radii ? &radii_ : nullptr);
  device_->Synchronize();
  auto t3 = Clock::now();
  const double c3 = ProcessCpuSeconds();
  // As on the host path, the last iteration's model is neither densified
  // nor reset.
  DensityEvent event;
  if (!last) {
    event = device_density_ ? device_->DensityStep(it)
                            : HostDensityStep(it, wants_radii);
  }
  const size_t num_gaussians = device_->NumGaussians();
  if (num_gaussians == 0) FailAllPruned(it);
  auto t4 = Clock::now();
  const double c4 = ProcessCpuSeconds();
  // Host path's rules: no step after densification or on the last
  // iteration, none for the opacity group after a reset.
  if (!last && !event.densified) {
    device_->AdamStep(it, event.opacity_reset);
  }
  auto t5 = Clock::now();
  const double c5 = ProcessCpuSeconds();
  FillStepStats({t0, t1, t2, t3, t4, t5}, {c0, c1, c2, c3, c4, c5}, event,
                num_gaussians, &stats);
  iteration_ = it;
  elapsed_seconds_ += Seconds(t0, t5);
  return stats;
}

DensityEvent Trainer::HostDensityStep(int64_t it, bool wants_radii) {
  const bool may_change = strategy_->MayChangeModel(it);
  if (may_change) SyncToHost();
  const size_t before = model_.size();
  const DensityEvent event = strategy_->PostBackward(
      it, grads_, wants_radii ? &radii_ : nullptr, &model_, &adam_);
  if (may_change) {
    device_->MarkHostModelEdited();
    device_->MarkHostAdamEdited();
    device_->PushIfStale();
  } else if (event.densified || event.opacity_reset ||
             model_.size() != before) {
    Fail("training stopped at iteration " + std::to_string(it) +
         ": the density strategy changed the model on an iteration its "
         "MayChangeModel excludes");
  }
  return event;
}

void Trainer::AppendLog(const IterationStats& stats, const EvalResult* test) {
  nlohmann::json j;
  j["iteration"] = stats.iteration;
  j["loss"] = stats.loss.total;
  j["l1"] = stats.loss.l1;
  j["ssim"] = stats.loss.ssim;
  j["num_gaussians"] = stats.num_gaussians;
  j["seconds"] = std::round(elapsed_seconds_ * 1000) / 1000;
  if (test) {
    j["test_psnr"] = test->psnr;
    j["test_ssim"] = test->ssim;
    j["test_l1"] = test->l1;
  }
  log_lines_.push_back(j.dump());
}

void Trainer::FlushLog() {
  if (options_.log_path.empty()) return;
  std::string text;
  for (const std::string& line : log_lines_) text += line + "\n";
  AtomicWriteFile(options_.log_path, text);
}

void Trainer::Run() {
  std::unique_ptr<ProgressBar> bar;
  if (options_.show_progress) {
    bar =
        std::make_unique<ProgressBar>("train", options_.iterations, iteration_);
  }
  auto last_flush = Clock::now();
  RunningAverage loss(0.6);
  while (iteration_ < options_.iterations) {
    const int64_t it = iteration_ + 1;
    const bool test_now = !options_.test_views.empty() &&
                          std::find(options_.test_iterations.begin(),
                                    options_.test_iterations.end(),
                                    it) != options_.test_iterations.end();
    // As Inria's training_report: held-out views are scored before this
    // iteration's densification, opacity reset and step, so a test at a
    // reset iteration (3000, 6000, ...) does not score the reset model.
    EvalResult test;
    if (test_now) {
      const double test_start = bar ? bar->ElapsedSeconds() : 0;
      // model() brings a GPU run's model to the host first.
      test = EvaluateViews(*rasterizer_, model(), views_, options_.test_views,
                           options_.background, active_sh_degree_);
      if (bar) {
        bar->AddSideWork(
            "test", bar->ElapsedSeconds() - test_start,
            std::count_if(options_.test_iterations.begin(),
                          options_.test_iterations.end(), [&](int64_t t) {
                            return t > it && t <= options_.iterations;
                          }));
      }
    }
    const IterationStats stats = Step();
    loss.Add(stats.loss.total);
    if (test_now || it == 1 || it == options_.iterations ||
        (options_.log_every > 0 && it % options_.log_every == 0)) {
      AppendLog(stats, test_now ? &test : nullptr);
    }
    if (options_.checkpoint_every > 0 && it % options_.checkpoint_every == 0 &&
        !options_.checkpoint_path.empty()) {
      // Log first: a kill between the two then leaves log lines past the
      // checkpoint (dropped on resume), never a gap before it.
      FlushLog();
      SaveCheckpoint(options_.checkpoint_path);
      last_flush = Clock::now();
    } else if (Seconds(last_flush, Clock::now()) > 30) {
      FlushLog();
      last_flush = Clock::now();
    }
    if (bar) {
      if (test_now) {
        // A result worth keeping: its own line, not the overwritten bar.
        char line[160];
        std::snprintf(line, sizeof(line),
                      "train: iteration %lld: held-out PSNR %.2f dB, SSIM "
                      "%.4f, L1 %.4f (%zu %s)",
                      static_cast<long long>(it), test.psnr, test.ssim, test.l1,
                      test.num_views, test.num_views == 1 ? "view" : "views");
        bar->Print(line);
      }
      char status[96];
      std::snprintf(status, sizeof(status), "loss %.4f  %zu Gaussians",
                    loss.value(), stats.num_gaussians);
      // Steps cost in proportion to the Gaussians, which densification
      // keeps adding until densify_until_iter.
      bar->SetLoad(double(stats.num_gaussians),
                   options_.density.densify_until_iter);
      bar->Update(it, status);
    }
  }
  FlushLog();
  if (bar) {
    // The device's count: the host model may be behind.
    bar->Finish(
        std::to_string(device_ ? device_->NumGaussians() : model_.size()) +
        " Gaussians");
  }
}

TrainingCheckpoint Trainer::MakeCheckpoint() const {
  // A GPU run's model and moments come down first (~710 bytes per Gaussian).
  SyncToHost();
  TrainingCheckpoint c;
  c.iteration = iteration_;
  c.active_sh_degree = active_sh_degree_;
  c.elapsed_seconds = elapsed_seconds_;
  c.model = model_;
  for (int g = 0; g < kNumParamGroups; ++g) {
    c.adam[g] = adam_.state(static_cast<ParamGroup>(g));
  }
  c.adam_rejected = adam_.rejected_total();
  // On the device the CPU strategy's bytes too: checkpoints resume on
  // either device.
  c.density_state =
      device_density_ ? device_->SaveDensityState() : strategy_->SaveState();
  c.rng_state = RngState(rng_);
  c.view_stack = view_stack_;
  c.run_signature = RunSignature();
  return c;
}

void Trainer::SaveCheckpoint(const std::string& path) {
  WriteCheckpoint(path, MakeCheckpoint());
  last_checkpoint_ = path;
  last_checkpoint_iteration_ = iteration_;
}

void Trainer::Resume(const std::string& checkpoint_path) {
  TrainingCheckpoint c = ReadCheckpoint(checkpoint_path);
  if (c.model.sh_degree != model_.sh_degree) {
    FailAt(checkpoint_path,
           "checkpoint has SH degree " + std::to_string(c.model.sh_degree) +
               ", this run " + std::to_string(model_.sh_degree));
  }
  if (c.run_signature != RunSignature()) {
    FailAt(checkpoint_path,
           "checkpoint was written by a run with other "
           "options: " +
               c.run_signature + " vs " + RunSignature());
  }
  model_ = std::move(c.model);
  adam_.Init(model_);
  for (int g = 0; g < kNumParamGroups; ++g) {
    AdamGroupState& s = adam_.state(static_cast<ParamGroup>(g));
    if (c.adam[g].exp_avg.size() != s.exp_avg.size() ||
        c.adam[g].exp_avg_sq.size() != s.exp_avg_sq.size() ||
        c.adam[g].exp_avg_q.size() != s.exp_avg_q.size() ||
        c.adam[g].exp_avg_sq_shared.size() != s.exp_avg_sq_shared.size() ||
        c.adam[g].exp_avg_h.size() != s.exp_avg_h.size() ||
        c.adam[g].exp_avg_sq_h.size() != s.exp_avg_sq_h.size()) {
      FailAt(checkpoint_path,
             "checkpoint optimiser state does not match "
             "its model");
    }
    s = std::move(c.adam[g]);
  }
  adam_.set_rejected_total(c.adam_rejected);
  strategy_->Init(model_);
  try {
    strategy_->LoadState(c.density_state);
  } catch (const Error& e) {
    FailAt(checkpoint_path, e.what());
  }
  std::istringstream rng_in(c.rng_state);
  rng_in >> rng_;
  if (!rng_in) FailAt(checkpoint_path, "checkpoint RNG state is corrupt");
  for (uint32_t v : c.view_stack) {
    if (v >= train_views_.size()) {
      FailAt(checkpoint_path, "checkpoint view order does not match");
    }
  }
  view_stack_ = std::move(c.view_stack);
  iteration_ = c.iteration;
  active_sh_degree_ = c.active_sh_degree;
  elapsed_seconds_ = c.elapsed_seconds;
  last_checkpoint_ = checkpoint_path;
  last_checkpoint_iteration_ = iteration_;
  // The device copies are rebuilt from the restored ones at the next step.
  if (device_) {
    device_->MarkHostModelEdited();
    device_->MarkHostAdamEdited();
    if (device_density_) device_->LoadDensityState(c.density_state);
  }
  // Keep the log lines the checkpoint covers.
  log_lines_.clear();
  if (!options_.log_path.empty() &&
      std::filesystem::exists(options_.log_path)) {
    std::ifstream in(options_.log_path);
    std::string line;
    while (std::getline(in, line)) {
      const auto j = nlohmann::json::parse(line, nullptr, false);
      if (j.is_discarded() || !j.contains("iteration")) continue;
      if (j["iteration"].get<int64_t>() <= iteration_) {
        log_lines_.push_back(line);
      }
    }
  }
}

size_t Trainer::StateBytesPerGaussian() const {
  const size_t params =
      (3 + 3 + 4 + 1 + 3 + model_.sh_rest_stride()) * sizeof(float);
  return params + adam_.BytesPerGaussian() +
         GradientBytesPerGaussian(model_, grads_.compact_sh) +
         strategy_->BytesPerGaussian();
}

}  // namespace watergs
