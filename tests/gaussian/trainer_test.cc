// Tests for the training loop on a small synthetic scene rendered by the CPU
// rasterizer: the loss goes down, resuming a checkpoint gives bit-identical
// results, a non-finite loss stops training and keeps the last checkpoint.
// TrainerCuda tests check the GPU-resident step (cuda/cuda_training_step.h)
// against the CPU trainer and itself; they skip without a GPU.
#include "gaussian/trainer.h"

#include <gtest/gtest.h>
#include <omp.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/device.h"
#include "gaussian/device_training_step.h"
#include "gaussian/projection.h"
#include "gaussian/util/error.h"
#include "tests/common/backend_parity.h"
#include "tests/common/bit_identical.h"
#include "tests/common/cuda_test.h"
#include "tests/common/look_at.h"

namespace watergs {
namespace {

std::string TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_trainer_" + name + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

GaussianModel RandomBall(int n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianModel m;
  m.sh_degree = 1;
  m.Resize(n);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      m.means[3 * i + a] = 0.8f * u(rng);
      m.log_scales[3 * i + a] = std::log(scale * (1.2f + 0.5f * u(rng)));
      m.sh_dc[3 * i + a] = 1.2f * u(rng);
    }
    m.quats[4 * i] = 1;
    m.quats[4 * i + 1] = 0.3f * u(rng);
    m.opacity_logits[i] = 1.0f + u(rng);
  }
  return m;
}

struct Scene {
  InMemoryViews views;
  std::vector<size_t> train;
  GaussianModel init;
};

// Ground truth rendered from a random model; training starts from another.
Scene MakeScene() {
  Scene s;
  const GaussianModel truth = RandomBall(60, 1, 0.12f);
  auto rasterizer = MakeCpuRasterizer();
  for (int v = 0; v < 6; ++v) {
    const double a = 2 * M_PI * v / 6;
    const RenderCamera cam = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 40, 32);
    ImageRGB image;
    rasterizer->Forward(truth, cam, RenderOptions{}, &image, nullptr);
    s.views.Add("view" + std::to_string(v), cam, image);
    s.train.push_back(v);
  }
  s.init = RandomBall(40, 2, 0.1f);
  return s;
}

TrainerOptions SmallRun(int64_t iterations) {
  TrainerOptions o;
  o.iterations = iterations;
  o.seed = 5;
  o.adam.position_lr_max_steps = iterations;
  o.sh_increase_interval = 10;
  // Compressed schedule so that densification and resets happen.
  o.density.densify_from_iter = 4;
  o.density.densification_interval = 6;
  o.density.densify_until_iter = 36;
  o.density.opacity_reset_interval = 18;
  o.density.grad_threshold = 1e-5;
  return o;
}

// Renders NaN from the n-th forward pass on.
class NanAfter : public Rasterizer {
 public:
  explicit NanAfter(int n) : n_(n), inner_(MakeCpuRasterizer()) {}
  void Forward(const GaussianModel& model, const RenderCamera& camera,
               const RenderOptions& options, ImageRGB* image,
               std::unique_ptr<RenderContext>* context) override {
    inner_->Forward(model, camera, options, image, context);
    if (++calls_ >= n_)
      image->data[5] = std::numeric_limits<float>::quiet_NaN();
  }
  void Backward(const GaussianModel& model, const RenderContext& context,
                const ImageRGB& grad_image, GaussianGradients* grads) override {
    inner_->Backward(model, context, grad_image, grads);
  }

 private:
  int n_, calls_ = 0;
  std::unique_ptr<Rasterizer> inner_;
};

// A device step emulated on the host: its "device" model and Adam are
// separate copies that meet the trainer's only through Pull and Push, with
// the CPU rasterizer, loss, Adam and (once it takes density control) an
// Inria strategy of its own doing what the CUDA kernels do. A run through it
// equals the host run bit for bit exactly when the trainer syncs at the
// right points (a stale read or a lost edit changes the result).
class EmulatedDeviceStep : public DeviceTrainingStep {
 public:
  EmulatedDeviceStep(GaussianModel* host_model, Adam* host_adam)
      : host_model_(host_model), host_adam_(host_adam), adam_(*host_adam) {
    grads_.compact_sh = true;
  }
  void Forward(const RenderCamera& camera, const RenderOptions& options,
               const ImageRGB& truth) override {
    PushIfStale();
    camera_ = camera;
    truth_ = truth;
    rasterizer_.Forward(model_, camera, options, &render_, &context_);
  }
  LossTerms Loss() override {
    return loss_.Evaluate(render_, truth_, &grad_image_);
  }
  void Backward(GaussianGradients* statistics,
                std::vector<float>* radii) override {
    rasterizer_.Backward(model_, *context_, grad_image_, &grads_);
    context_.reset();
    if (radii) ComputeScreenRadii(model_, camera_, grads_.visible, radii);
    if (statistics) {
      *statistics = GaussianGradients{};
      statistics->visible = grads_.visible;
      statistics->mean2d_grad_norm_ndc = grads_.mean2d_grad_norm_ndc;
    }
  }
  size_t AdamStep(int64_t iteration, bool skip_opacity) override {
    adam_.SetIteration(iteration);
    const bool enabled = adam_.GroupEnabled(ParamGroup::kOpacity);
    if (skip_opacity) adam_.SetGroupEnabled(ParamGroup::kOpacity, false);
    const size_t rejected = adam_.Step(grads_, &model_);
    adam_.SetGroupEnabled(ParamGroup::kOpacity, enabled);
    host_model_stale_ = host_adam_stale_ = true;
    ++steps;
    return rejected;
  }
  void Synchronize() override {}
  void PullModel() override {
    if (host_model_stale_) *host_model_ = model_, ++pulls;
    host_model_stale_ = false;
  }
  // As CudaModelMirror::PullAdam: the host Adam is sized from the pulled
  // host model, then takes the moments, step counts and rejected count.
  void PullAdam() override {
    if (!host_adam_stale_) return;
    PullModel();
    host_adam_->Init(*host_model_);
    for (int g = 0; g < kNumParamGroups; ++g) {
      const ParamGroup group = static_cast<ParamGroup>(g);
      host_adam_->state(group) = adam_.state(group);
    }
    host_adam_->set_rejected_total(adam_.rejected_total());
    ++pulls;
    host_adam_stale_ = false;
  }
  void MarkHostModelEdited() override {
    host_model_stale_ = false;
    device_model_stale_ = true;
  }
  void MarkHostAdamEdited() override {
    host_adam_stale_ = false;
    device_adam_stale_ = true;
  }
  void PushIfStale() override {
    if (device_model_stale_) model_ = *host_model_, ++pushes;
    if (device_adam_stale_) adam_ = *host_adam_, ++pushes;
    device_model_stale_ = device_adam_stale_ = false;
  }
  size_t NumGaussians() const override {
    return device_model_stale_ ? host_model_->size() : model_.size();
  }
  bool TakeDensityControl(const DensityOptions& options, double scene_extent,
                          const std::string& state) override {
    density_ = MakeInriaDensityStrategy(options, scene_extent);
    LoadDensityState(state);
    return true;
  }
  DensityEvent DensityStep(int64_t iteration) override {
    std::vector<float> radii;
    const bool wants_radii = density_->WantsRadii(iteration);
    if (wants_radii)
      ComputeScreenRadii(model_, camera_, grads_.visible, &radii);
    const DensityEvent event = density_->PostBackward(
        iteration, grads_, wants_radii ? &radii : nullptr, &model_, &adam_);
    if (event.densified || event.opacity_reset) {
      host_model_stale_ = host_adam_stale_ = true;
      ++density_changes;
    }
    return event;
  }
  std::string SaveDensityState() const override {
    return density_->SaveState();
  }
  void LoadDensityState(const std::string& state) override {
    density_->Init(device_model_stale_ ? *host_model_ : model_);
    density_->LoadState(state);
  }

  // Transfers, steps and density changes on the device so far (all
  // instances).
  static inline int pulls = 0, pushes = 0, steps = 0, density_changes = 0;

 private:
  GaussianModel* host_model_;
  Adam* host_adam_;
  bool host_model_stale_ = false, host_adam_stale_ = false;
  bool device_model_stale_ = true, device_adam_stale_ = true;
  GaussianModel model_;
  Adam adam_;
  CpuRasterizer rasterizer_;
  TrainingLoss loss_{0.2};
  RenderCamera camera_;
  ImageRGB truth_, render_, grad_image_;
  std::unique_ptr<RenderContext> context_;
  GaussianGradients grads_;
  std::unique_ptr<DensityStrategy> density_;
};

std::unique_ptr<DeviceTrainingStep> MakeEmulatedStep(GaussianModel* model,
                                                     Adam* adam) {
  return std::make_unique<EmulatedDeviceStep>(model, adam);
}

// Every parameter group and every optimiser moment, byte for byte.
void ExpectSameState(Trainer& a, Trainer& b) {
  testing::ExpectBitIdenticalModels(a.model(), b.model());
  for (int g = 0; g < kNumParamGroups; ++g) {
    const ParamGroup group = static_cast<ParamGroup>(g);
    testing::ExpectSameAdamGroup(a.adam().state(group), b.adam().state(group),
                                 GroupName(group));
  }
  EXPECT_EQ(a.adam().rejected_total(), b.adam().rejected_total());
}

TEST(Trainer, LossDecreases) {
  Scene s = MakeScene();
  TrainerOptions o = SmallRun(60);
  o.density.densify_until_iter = 0;
  Trainer trainer(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  const EvalResult before = EvaluateViews(trainer.rasterizer(), trainer.model(),
                                          s.views, s.train, {0, 0, 0}, 0);
  trainer.Run();
  const EvalResult after = EvaluateViews(trainer.rasterizer(), trainer.model(),
                                         s.views, s.train, {0, 0, 0}, 1);
  EXPECT_GT(after.psnr, before.psnr + 1.0);
  EXPECT_EQ(trainer.active_sh_degree(), 1);
  EXPECT_EQ(trainer.model().CountNonFinite(), 0u);
}

// A run from SfM points starts at SH degree 0 (Inria); one refining a
// trained model starts at the degree asked, capped by the model's.
TEST(Trainer, InitialShDegreeIsCappedByTheModel) {
  Scene s = MakeScene();
  ASSERT_EQ(s.init.sh_degree, 1);
  TrainerOptions o = SmallRun(2);
  Trainer from_points(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_EQ(from_points.active_sh_degree(), 0);
  o.initial_sh_degree = 3;
  Trainer refining(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_EQ(refining.active_sh_degree(), 1);
  refining.Step();
  EXPECT_EQ(refining.active_sh_degree(), 1);
}

// Inria saves the model before the last iteration's density control: a run
// that ends on a densification and opacity-reset iteration must write the
// model its held-out test scored, not the freshly reset one.
TEST(Trainer, LastIterationIsNeitherDensifiedNorReset) {
  Scene s = MakeScene();
  TrainerOptions o = SmallRun(36);
  o.density.densification_interval = 6;
  o.density.opacity_reset_interval = 18;
  o.density.densify_until_iter = 40;  // 36 is a densify and reset iteration
  o.test_views = {0, 3};
  o.test_iterations = {36};
  Trainer trainer(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  trainer.Run();
  const EvalResult final_views =
      EvaluateViews(trainer.rasterizer(), trainer.model(), s.views, {0, 3},
                    {0, 0, 0}, trainer.active_sh_degree());
  double logged_psnr = -1;
  for (const std::string& line : trainer.log_lines()) {
    const nlohmann::json j = nlohmann::json::parse(line);
    if (j["iteration"] == 36 && j.contains("test_psnr"))
      logged_psnr = j["test_psnr"];
  }
  ASSERT_GT(logged_psnr, 0);
  EXPECT_NEAR(final_views.psnr, logged_psnr, 1e-6);
  float max_opacity_logit = -100;
  for (float a : trainer.model().opacity_logits)
    max_opacity_logit = std::max(max_opacity_logit, a);
  // A reset would cap every opacity at 0.01 (logit about -4.6).
  EXPECT_GT(max_opacity_logit, -4.0f);
}

TEST(Trainer, ResumeGivesTheSameResultAsAnUninterruptedRun) {
  Scene s = MakeScene();
  const std::string dir = TempDir("resume");
  TrainerOptions o = SmallRun(40);
  o.log_every = 1;
  o.log_path = dir + "/full.jsonl";
  Trainer full(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  full.Run();
  ASSERT_NE(full.model().size(), s.init.size());  // densification happened

  // The same run, killed at iteration 23 (after a checkpoint at 20) ...
  o.log_path = dir + "/run.jsonl";
  o.checkpoint_path = dir + "/run.ckpt";
  o.checkpoint_every = 10;
  Trainer crashed(o, s.views, s.train, s.init, 3.3,
                  std::make_unique<NanAfter>(23));
  EXPECT_THROW(crashed.Run(), Error);
  // ... and resumed.
  Trainer resumed(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  resumed.Resume(o.checkpoint_path);
  EXPECT_EQ(resumed.iteration(), 20);
  resumed.Run();
  ExpectSameState(full, resumed);
  // The log has one line per iteration, 1..40, with the required fields,
  // and the same losses as the uninterrupted run.
  std::ifstream log(o.log_path), full_log(dir + "/full.jsonl");
  std::string line, full_line;
  int64_t expected = 1;
  while (std::getline(log, line) && std::getline(full_log, full_line)) {
    const auto j = nlohmann::json::parse(line);
    const auto f = nlohmann::json::parse(full_line);
    EXPECT_EQ(j["iteration"].get<int64_t>(), expected++);
    EXPECT_EQ(j["loss"], f["loss"]);
    EXPECT_EQ(j["num_gaussians"], f["num_gaussians"]);
    EXPECT_TRUE(j.contains("seconds"));
  }
  EXPECT_EQ(expected, 41);
}

TEST(Trainer, HalfMomentRunResumesBitIdentically) {
  Scene s = MakeScene();
  const std::string dir = TempDir("resume_half");
  TrainerOptions o = SmallRun(30);
  o.adam.half_moments = true;
  Trainer full(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  full.Run();
  o.checkpoint_path = dir + "/run.ckpt";
  o.checkpoint_every = 10;
  Trainer crashed(o, s.views, s.train, s.init, 3.3,
                  std::make_unique<NanAfter>(15));
  EXPECT_THROW(crashed.Run(), Error);
  Trainer resumed(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  resumed.Resume(o.checkpoint_path);
  resumed.Run();
  ExpectSameState(full, resumed);
  EXPECT_FALSE(full.adam().state(ParamGroup::kFRest).exp_avg_sq_h.empty());
  // A float-moment run refuses the half-moment checkpoint.
  o.adam.half_moments = false;
  Trainer other(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_THROW(other.Resume(o.checkpoint_path), Error);
}

// The budget: at most 600 bytes of training state per Gaussian at
// SH degree 3 with bfloat16 moments and factored SH gradients.
TEST(Trainer, HalfMomentStateFitsSixHundredBytesAtShDegreeThree) {
  Scene s = MakeScene();
  GaussianModel init = s.init;
  GaussianModel degree3;
  degree3.sh_degree = 3;
  degree3.Resize(init.size());
  degree3.means = init.means;
  degree3.log_scales = init.log_scales;
  degree3.quats = init.quats;
  degree3.opacity_logits = init.opacity_logits;
  degree3.sh_dc = init.sh_dc;
  for (bool half : {false, true}) {
    TrainerOptions o = SmallRun(1);
    o.adam.half_moments = half;
    Trainer trainer(o, s.views, s.train, degree3, 3.3, MakeCpuRasterizer());
    const size_t params = 59 * 4;  // 3 + 3 + 4 + 1 + 3 + 45 floats
    // Moments: positions in float, the other 56 values per Gaussian in
    // bfloat16 or float, two moments each.
    const size_t moments = 2 * (3 * 4 + 56 * (half ? 2 : 4));
    // Gradients: 11 floats of geometry and opacity, 6 SH factors, two
    // densification norms and a visibility byte.
    const size_t grads = (11 + 6 + 2) * 4 + 1;
    EXPECT_GE(trainer.StateBytesPerGaussian(), params + moments + grads);
    EXPECT_LE(trainer.StateBytesPerGaussian(),
              params + moments + grads + 16);  // density-control statistics
    if (half) {
      EXPECT_LE(trainer.StateBytesPerGaussian(), 600u);
    }
  }
}

// The README's claim that a run is the same for any thread count, float32
// and bfloat16 moments alike: OpenMP splits the rasterizer's tiles, the
// loss's row strips and Adam's blocks differently at 1, 2 and 3 threads, so
// every reduction must have a fixed order and the stochastic rounding of
// bfloat16 moments must not follow the threads. 3 threads split the 100
// rows unevenly (33, 33, 34), which 2 do not. Sizes chosen so that each
// of those runs in parallel: 128x100 views (56 tiles; the loss goes parallel
// from 32k values), SH degree 3 and 1,500 Gaussians (Adam goes parallel
// from 32k values per group: here the SH coefficients, over 6 blocks of
// 256 Gaussians); the compressed schedule densifies, resets opacities and
// raises the SH degree within the run.
TEST(Trainer, SameRunForAnyThreadCount) {
  const GaussianModel ball = RandomBall(1500, 3, 0.05f);
  GaussianModel init;
  init.sh_degree = 3;
  init.Resize(ball.size());
  init.means = ball.means;
  init.log_scales = ball.log_scales;
  init.quats = ball.quats;
  init.opacity_logits = ball.opacity_logits;
  init.sh_dc = ball.sh_dc;
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  for (float& v : init.sh_rest) v = u(rng);
  InMemoryViews views;
  std::vector<size_t> train;
  for (int v = 0; v < 6; ++v) {
    const double a = 2 * M_PI * v / 6;
    const RenderCamera cam = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 128, 100);
    ImageRGB image;
    MakeCpuRasterizer()->Forward(RandomBall(60, 1, 0.12f), cam, RenderOptions{},
                                 &image, nullptr);
    views.Add("view" + std::to_string(v), cam, image);
    train.push_back(v);
  }
  const int saved_threads = omp_get_max_threads();
  for (bool half : {false, true}) {
    SCOPED_TRACE(half ? "bfloat16 moments" : "float32 moments");
    TrainerOptions o = SmallRun(30);
    o.adam.half_moments = half;
    o.log_every = 1;
    auto run = [&](int threads) {
      omp_set_num_threads(threads);
      auto trainer = std::make_unique<Trainer>(o, views, train, init, 3.3,
                                               MakeCpuRasterizer());
      trainer->Run();
      omp_set_num_threads(saved_threads);
      return trainer;
    };
    const std::unique_ptr<Trainer> one = run(1);
    ASSERT_NE(one->model().size(), init.size());  // densification happened
    EXPECT_EQ(one->active_sh_degree(), 3);
    for (int threads : {2, 3}) {
      SCOPED_TRACE(std::to_string(threads) + " threads");
      const std::unique_ptr<Trainer> other = run(threads);
      ExpectSameState(*one, *other);
      // The logged losses too (the loss value is a reduction of its own).
      ASSERT_EQ(one->log_lines().size(), other->log_lines().size());
      for (size_t i = 0; i < one->log_lines().size(); ++i) {
        auto a = nlohmann::json::parse(one->log_lines()[i]);
        auto b = nlohmann::json::parse(other->log_lines()[i]);
        a.erase("seconds"), b.erase("seconds");
        EXPECT_EQ(a, b) << "log line " << i;
      }
    }
  }
}

TEST(Trainer, ResumeRefusesAnotherRunsCheckpoint) {
  Scene s = MakeScene();
  const std::string dir = TempDir("refuse");
  TrainerOptions o = SmallRun(10);
  Trainer a(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  a.Step();
  a.SaveCheckpoint(dir + "/a.ckpt");
  o.seed = 6;
  Trainer b(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_THROW(b.Resume(dir + "/a.ckpt"), Error);
  // Another density schedule is another run too.
  o.seed = 5;
  o.density.densify_until_iter += 100;
  Trainer c(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_THROW(c.Resume(dir + "/a.ckpt"), Error);
  o.density.densify_until_iter -= 100;
  Trainer same(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  EXPECT_NO_THROW(same.Resume(dir + "/a.ckpt"));
}

TEST(Trainer, NonFiniteLossStopsAndKeepsTheLastCheckpoint) {
  Scene s = MakeScene();
  const std::string dir = TempDir("nan");
  TrainerOptions o = SmallRun(20);
  o.checkpoint_path = dir + "/run.ckpt";
  o.checkpoint_every = 5;
  Trainer trainer(o, s.views, s.train, s.init, 3.3,
                  std::make_unique<NanAfter>(8));
  try {
    trainer.Run();
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("iteration 8"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not finite"), std::string::npos) << msg;
    EXPECT_NE(msg.find("run.ckpt (iteration 5)"), std::string::npos) << msg;
  }
  EXPECT_EQ(ReadCheckpoint(dir + "/run.ckpt").iteration, 5);
  EXPECT_EQ(trainer.model().CountNonFinite(), 0u);
}

TEST(Trainer, StateBytesPerGaussianCountsEveryBuffer) {
  Scene s = MakeScene();
  TrainerOptions o = SmallRun(1);
  Trainer trainer(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  // SH degree 1: 3 + 3 + 4 + 1 + 3 + 9 = 23 floats per parameter copy
  // (parameters and two moments); the gradient holds the 11 geometry and
  // opacity floats and 6 factors of the SH gradient.
  const size_t params = 23 * 4;
  EXPECT_GE(trainer.StateBytesPerGaussian(), 3 * params + (11 + 6) * 4);
}

// Transfers of one emulated device run (counted from its first step).
struct Transfers {
  int pulls = 0, pushes = 0, steps = 0, density_changes = 0;
};

// A run with densification (6, 12, 18, 24, 30), an opacity reset (18),
// held-out evaluation (18, 25, 40) and checkpoints (15, 30) through the
// emulated device step, with the trainer's own Inria strategy or, when
// `pass_strategy`, the same strategy passed in (which stays on the host).
// Expects it to equal the host run bit for bit (model, moments, log,
// checkpoints) and returns its transfers.
Transfers ExpectEmulatedRunEqualsHostRun(bool pass_strategy) {
  Scene s = MakeScene();
  const std::string dir = TempDir("emulated");
  TrainerOptions o = SmallRun(40);
  o.log_every = 1;
  o.test_views = {0, 3};
  o.test_iterations = {18, 25, 40};
  o.checkpoint_every = 15;
  o.checkpoint_path = dir + "/host.ckpt";
  Trainer host(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  host.Run();
  o.checkpoint_path = dir + "/device.ckpt";
  std::unique_ptr<DensityStrategy> strategy;
  if (pass_strategy) {
    // The trainer's own seeding of its built-in strategy.
    DensityOptions density = o.density;
    density.seed = o.seed ^ 0x9e3779b97f4a7c15ull;
    strategy = MakeInriaDensityStrategy(density, 3.3);
  }
  Trainer device(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer(),
                 std::move(strategy));
  device.UseDeviceStep(MakeEmulatedStep);
  EmulatedDeviceStep::pulls = EmulatedDeviceStep::pushes = 0;
  EmulatedDeviceStep::steps = EmulatedDeviceStep::density_changes = 0;
  device.Run();
  const Transfers transfers{
      EmulatedDeviceStep::pulls, EmulatedDeviceStep::pushes,
      EmulatedDeviceStep::steps, EmulatedDeviceStep::density_changes};
  EXPECT_NE(host.model().size(), s.init.size());
  ExpectSameState(host, device);
  EXPECT_EQ(host.log_lines().size(), device.log_lines().size());
  for (size_t i = 0; i < host.log_lines().size(); ++i) {
    auto a = nlohmann::json::parse(host.log_lines()[i]);
    auto b = nlohmann::json::parse(device.log_lines()[i]);
    a.erase("seconds"), b.erase("seconds");
    EXPECT_EQ(a, b) << "log line " << i;
  }
  // The checkpoints hold the same state (a stale host copy would not), and
  // the device's density state is written as the CPU strategy's bytes.
  const TrainingCheckpoint a = ReadCheckpoint(dir + "/host.ckpt");
  const TrainingCheckpoint b = ReadCheckpoint(dir + "/device.ckpt");
  EXPECT_EQ(a.iteration, 30);
  EXPECT_EQ(a.model.means, b.model.means);
  EXPECT_EQ(a.adam[0].exp_avg_sq, b.adam[0].exp_avg_sq);
  EXPECT_EQ(a.density_state, b.density_state);
  return transfers;
}

// The device path's sync protocol, on the host emulation, with the
// trainer's built-in strategy: the device step owns density control, so the
// model and moments go up once at the start and come down only for the
// three evaluations (model) and the two checkpoints (both): no transfer at
// the densification and reset iterations.
TEST(TrainerDeviceProtocol, EmulatedDeviceRunEqualsTheHostRun) {
  const Transfers t = ExpectEmulatedRunEqualsHostRun(false);
  EXPECT_GT(t.steps, 30);
  // Densified at 6, 12, 18, 24, 30 (18 also resets) on the device.
  EXPECT_EQ(t.density_changes, 5);
  EXPECT_EQ(t.pushes, 2);
  EXPECT_EQ(t.pulls, 3 + 2 * 2);
}

// A strategy passed in stays on the host: model and moments come down and
// go back up at each of the five densification / reset iterations besides
// the evaluations, checkpoints and the start.
TEST(TrainerDeviceProtocol, PassedStrategyKeepsTheHostRoundTrip) {
  const Transfers t = ExpectEmulatedRunEqualsHostRun(true);
  EXPECT_GT(t.steps, 30);
  EXPECT_EQ(t.density_changes, 0);
  EXPECT_LE(t.pulls, 2 * 5 + 3 + 2 * 2);
  EXPECT_EQ(t.pushes, 2 + 2 * 5);
}

// Resuming a device-path trainer pushes the restored state to the device:
// the resumed run ends where an uninterrupted host run does.
TEST(TrainerDeviceProtocol, EmulatedDeviceResumeEqualsTheHostRun) {
  Scene s = MakeScene();
  const std::string dir = TempDir("emulated_resume");
  TrainerOptions o = SmallRun(40);
  Trainer host(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  host.Run();
  Trainer first(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  first.UseDeviceStep(MakeEmulatedStep);
  for (int i = 0; i < 20; ++i) first.Step();
  first.SaveCheckpoint(dir + "/run.ckpt");
  Trainer resumed(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  resumed.UseDeviceStep(MakeEmulatedStep);
  resumed.Step();  // the device now holds a state the resume must replace
  resumed.Resume(dir + "/run.ckpt");
  resumed.Run();
  ExpectSameState(host, resumed);
  // The device's checkpoint (its density state included) resumes on the
  // host path too.
  Trainer on_host(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  on_host.Resume(dir + "/run.ckpt");
  on_host.Run();
  ExpectSameState(host, on_host);
}

// The host edits the model and the moments after the device densified
// (the Gaussian count changed on the device): they go back up and the run
// continues as the host run does.
TEST(TrainerDeviceProtocol, HostEditsAfterADeviceDensificationContinue) {
  Scene s = MakeScene();
  const TrainerOptions o = SmallRun(20);
  Trainer host(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  host.Run();
  Trainer device(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  device.UseDeviceStep(MakeEmulatedStep);
  for (int i = 0; i < 14; ++i) device.Step();
  ASSERT_NE(device.model().size(), s.init.size());
  device.adam();           // pulled and marked edited
  device.mutable_model();  // the same for the model
  device.Run();
  ExpectSameState(host, device);
}

// Training steps with the CUDA rasterizer equal the CPU trainer's: the same
// losses to float rounding and the same parameters after Adam, including a
// density-control step (ExpectModelsAgree says how they may differ).
TEST(TrainerCuda, StepsMatchTheCpuTrainer) {
  WATERGS_REQUIRE_CUDA();
  Scene s = MakeScene();
  TrainerOptions o = SmallRun(6);
  // Densification needs iteration > densify_from_iter: 4 densifies.
  o.density.densify_from_iter = 3;
  o.density.densification_interval = 4;
  o.density.densify_until_iter = 6;
  Trainer cpu(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  Trainer gpu(o, s.views, s.train, s.init, 3.3, MakeRasterizer(Device::kCuda));
  for (int i = 0; i < 3; ++i) {
    const IterationStats a = cpu.Step(), b = gpu.Step();
    EXPECT_NEAR(a.loss.total, b.loss.total, 1e-5 * (1 + a.loss.total));
    EXPECT_NEAR(a.loss.ssim, b.loss.ssim, 1e-5);
  }
  testing::ExpectModelsAgree(cpu.model(), gpu.model(), o.adam, 3.3, 3);
  // Iteration 4 densifies from the accumulated screen-space gradients: the
  // same Gaussians are cloned, split and pruned.
  const IterationStats a = cpu.Step(), b = gpu.Step();
  EXPECT_GT(a.cloned + a.split, 0u);  // the comparison is not vacuous
  EXPECT_EQ(a.cloned, b.cloned);
  EXPECT_EQ(a.split, b.split);
  EXPECT_EQ(a.pruned, b.pruned);
  EXPECT_EQ(cpu.model().size(), gpu.model().size());
}

// Density control on the GPU (the trainer's built-in strategy runs as
// CudaDensityControl) takes the CPU trainer's decisions through the
// densifications at 6, 12 and 18 and the opacity reset at 18: the same
// clone / split / prune counts at every iteration, the same Gaussian count,
// parameters within ExpectModelsAgree's tolerance, and a checkpointed
// density state in the CPU strategy's layout that a CPU trainer resumes.
TEST(TrainerCuda, DeviceDensityControlMatchesTheCpuTrainer) {
  WATERGS_REQUIRE_CUDA();
  Scene s = MakeScene();
  const std::string dir = TempDir("cuda_density");
  const TrainerOptions o = SmallRun(20);
  Trainer cpu(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  Trainer gpu(o, s.views, s.train, s.init, 3.3, MakeRasterizer(Device::kCuda));
  size_t changed = 0;
  bool reset = false;
  for (int i = 0; i < 19; ++i) {
    const IterationStats a = cpu.Step(), b = gpu.Step();
    EXPECT_EQ(a.cloned, b.cloned) << "iteration " << a.iteration;
    EXPECT_EQ(a.split, b.split) << "iteration " << a.iteration;
    EXPECT_EQ(a.pruned, b.pruned) << "iteration " << a.iteration;
    ASSERT_EQ(a.num_gaussians, b.num_gaussians) << "iteration " << a.iteration;
    changed += a.cloned + a.split + a.pruned;
    if (a.iteration == 18) {
      const float cap = ResetOpacityLogit(10.f, o.density.reset_opacity);
      for (float logit : gpu.model().opacity_logits) ASSERT_LE(logit, cap);
      reset = true;
    }
  }
  EXPECT_GT(changed, 0u);  // the comparison is not vacuous
  EXPECT_TRUE(reset);
  testing::ExpectModelsAgree(cpu.model(), gpu.model(), o.adam, 3.3, 19);
  cpu.SaveCheckpoint(dir + "/cpu.ckpt");
  gpu.SaveCheckpoint(dir + "/gpu.ckpt");
  const TrainingCheckpoint a = ReadCheckpoint(dir + "/cpu.ckpt");
  const TrainingCheckpoint b = ReadCheckpoint(dir + "/gpu.ckpt");
  EXPECT_EQ(a.density_state.size(), b.density_state.size());
  Trainer resumed(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  resumed.Resume(dir + "/gpu.ckpt");
  const IterationStats last_cpu = cpu.Step(), last_resumed = resumed.Step();
  EXPECT_EQ(last_cpu.num_gaussians, last_resumed.num_gaussians);
  EXPECT_EQ(resumed.model().CountNonFinite(), 0u);
}

// A GPU run's checkpoint holds its device state (the trainer brings model
// and moments to the host first), and a GPU trainer resumed from it takes
// the steps the writing run takes, through densifications (18, 24) and an
// opacity reset (18). Two GPU runs differ only in the order of the
// backward pass's atomic sums, hence ExpectModelsAgree's tolerance.
TEST(TrainerCuda, CheckpointResumesToTheSameResult) {
  WATERGS_REQUIRE_CUDA();
  Scene s = MakeScene();
  const std::string dir = TempDir("cuda_resume");
  const TrainerOptions o = SmallRun(30);
  Trainer first(o, s.views, s.train, s.init, 3.3,
                MakeRasterizer(Device::kCuda));
  for (int i = 0; i < 14; ++i) first.Step();
  first.SaveCheckpoint(dir + "/run.ckpt");
  const TrainingCheckpoint c = ReadCheckpoint(dir + "/run.ckpt");
  EXPECT_EQ(c.iteration, 14);
  ASSERT_NE(c.model.size(), s.init.size());  // densified at 6 and 12
  EXPECT_EQ(c.model.means, first.model().means);
  EXPECT_EQ(c.model.sh_rest, first.model().sh_rest);
  const int xyz = static_cast<int>(ParamGroup::kXyz);
  EXPECT_EQ(c.adam[xyz].exp_avg_sq,
            first.adam().state(ParamGroup::kXyz).exp_avg_sq);
  EXPECT_GT(c.adam[xyz].step, 0);

  Trainer resumed(o, s.views, s.train, s.init, 3.3,
                  MakeRasterizer(Device::kCuda));
  resumed.Resume(dir + "/run.ckpt");
  ASSERT_EQ(resumed.iteration(), 14);
  for (int i = 0; i < 10; ++i) {
    const IterationStats a = first.Step(), b = resumed.Step();
    EXPECT_NEAR(a.loss.total, b.loss.total, 1e-5 * (1 + a.loss.total))
        << "iteration " << a.iteration;
    EXPECT_EQ(a.num_gaussians, b.num_gaussians) << "iteration " << a.iteration;
  }
  testing::ExpectModelsAgree(first.model(), resumed.model(), o.adam, 3.3, 10);
}

// A GPU run with densification, an opacity reset and held-out evaluation:
// the reset reaches the device model, every parameter and moment stays
// finite, the Gaussian count follows the CPU run's, and the held-out score
// logged at the last iteration is that of the model the run ends with
// (evaluation reads the device model, not a stale host copy).
TEST(TrainerCuda, DensityResetAndHeldOutRunStaysFiniteAndMatchesCpuCount) {
  WATERGS_REQUIRE_CUDA();
  Scene s = MakeScene();
  TrainerOptions o = SmallRun(40);
  o.test_views = {0, 3};
  o.test_iterations = {24, 40};
  Trainer cpu(o, s.views, s.train, s.init, 3.3, MakeCpuRasterizer());
  Trainer gpu(o, s.views, s.train, s.init, 3.3, MakeRasterizer(Device::kCuda));
  for (int i = 0; i < 18; ++i) {
    cpu.Step();
    gpu.Step();
  }
  // Iteration 18 reset every opacity to at most 0.01 and skipped its step.
  const float cap = ResetOpacityLogit(10.f, o.density.reset_opacity);
  for (float logit : gpu.model().opacity_logits) ASSERT_LE(logit, cap);
  cpu.Run();
  gpu.Run();
  EXPECT_EQ(gpu.iteration(), 40);
  EXPECT_EQ(gpu.model().CountNonFinite(), 0u);
  for (int g = 0; g < kNumParamGroups; ++g) {
    const AdamGroupState& state = gpu.adam().state(static_cast<ParamGroup>(g));
    for (const std::vector<float>* v : {&state.exp_avg, &state.exp_avg_sq}) {
      for (float x : *v)
        ASSERT_TRUE(std::isfinite(x)) << GroupName(ParamGroup(g));
    }
  }
  EXPECT_EQ(gpu.model().size(), cpu.model().size());
  std::map<int64_t, double> logged;
  for (const std::string& line : gpu.log_lines()) {
    const nlohmann::json j = nlohmann::json::parse(line);
    if (j.contains("test_psnr")) logged[j["iteration"]] = j["test_psnr"];
  }
  ASSERT_EQ(logged.size(), 2u);
  EXPECT_TRUE(std::isfinite(logged[24]));
  const EvalResult final_views =
      EvaluateViews(gpu.rasterizer(), gpu.model(), s.views, o.test_views,
                    o.background, gpu.active_sh_degree());
  EXPECT_NEAR(final_views.psnr, logged[40], 1e-6);
}

}  // namespace
}  // namespace watergs
