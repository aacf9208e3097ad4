// The 3DGS training loop (Inria's train.py): random view order per epoch
// from a seeded RNG, render, (1 - lambda) L1 + lambda D-SSIM, backward,
// density control through a DensityStrategy, Adam, SH degree raised every
// 1000 iterations. Writes a JSON-lines log and resumable checkpoints. Knows
// nothing of COLMAP: views come from a TrainingViews source.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/checkpoint.h"
#include "gaussian/density_strategy.h"
#include "gaussian/device_training_step.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// Cameras and ground-truth images the trainer learns from.
class TrainingViews {
 public:
  virtual ~TrainingViews() = default;
  virtual size_t NumViews() const = 0;
  // Name for logs and output files (e.g. the COLMAP image name).
  virtual std::string Name(size_t view) const = 0;
  virtual RenderCamera Camera(size_t view) const = 0;
  // Ground truth, float RGB in [0, 1], the camera's size.
  virtual std::shared_ptr<const ImageRGB> Image(size_t view) const = 0;
  // Whether the evaluation split holds the view out: LLFF's every 8th view
  // unless the source has its own split (a workspace's test_views.txt).
  virtual bool HeldOut(size_t view) const { return view % 8 == 0; }
};

// Views held in memory (tests, benchmarks, synthetic scenes).
class InMemoryViews : public TrainingViews {
 public:
  void Add(std::string name, const RenderCamera& camera, ImageRGB image);
  size_t NumViews() const override { return cameras_.size(); }
  std::string Name(size_t view) const override { return names_.at(view); }
  RenderCamera Camera(size_t view) const override { return cameras_.at(view); }
  std::shared_ptr<const ImageRGB> Image(size_t view) const override {
    return images_.at(view);
  }

 private:
  std::vector<std::string> names_;
  std::vector<RenderCamera> cameras_;
  std::vector<std::shared_ptr<const ImageRGB>> images_;
};

struct TrainerOptions {
  // Total iterations (Inria: 30000).
  int64_t iterations = 30000;
  // The active SH degree goes up by one every this many iterations.
  int64_t sh_increase_interval = 1000;
  // Active SH degree at the start (capped by the model's): 0 from SfM points
  // (Inria), the model's own when refining a trained model whose higher bands
  // already mean something.
  int initial_sh_degree = 0;
  // Colour behind the Gaussians.
  std::array<float, 3> background = {0.f, 0.f, 0.f};
  // Seeds the view order and density control's sampling.
  uint64_t seed = 0;
  // Weight of D-SSIM in the loss.
  double lambda_dssim = 0.2;
  // Optimiser settings (position_lr_max_steps included).
  AdamOptions adam;
  // Density control settings (used by the default strategy).
  DensityOptions density;
  // Checkpoint file and period (0 = only when asked).
  std::string checkpoint_path;
  int64_t checkpoint_every = 0;
  // JSON-lines log file ("" = none) and how often a line is written.
  std::string log_path;
  int64_t log_every = 10;
  // Held-out views evaluated at test_iterations (logged as test_psnr).
  std::vector<size_t> test_views;
  std::vector<int64_t> test_iterations;
  // Draw a progress bar on stderr.
  bool show_progress = false;
};

// Figures of one iteration.
struct IterationStats {
  int64_t iteration = 0;
  LossTerms loss;
  size_t num_gaussians = 0;
  // Seconds spent in each stage.
  double forward_s = 0, loss_s = 0, backward_s = 0, density_s = 0, adam_s = 0;
  // Process CPU seconds (all threads) of the same five stages.
  std::array<double, 5> cpu_s = {0, 0, 0, 0, 0};
  // What density control did.
  size_t cloned = 0, split = 0, pruned = 0;
};

// Mean metrics over views (Inria averages per-image PSNR and SSIM).
struct EvalResult {
  double psnr = 0, ssim = 0, l1 = 0;
  size_t num_views = 0;
  // Per view, in the order asked.
  std::vector<double> view_psnr, view_ssim;
};

// Renders `views` (indices into `source`) and compares with ground truth;
// `renders`, if non-null, receives the images (clamped to [0, 1]).
EvalResult EvaluateViews(Rasterizer& rasterizer, const GaussianModel& model,
                         const TrainingViews& source,
                         const std::vector<size_t>& views,
                         const std::array<float, 3>& background,
                         int active_sh_degree,
                         std::vector<ImageRGB>* renders = nullptr);

class Trainer {
 public:
  // `train_views` index into `views` (which must outlive the trainer);
  // `scene_extent` is Inria's cameras_extent. A null strategy means Inria's
  // ADC with options.density. With a CudaRasterizer and float32 moments the
  // model, moments and gradients live on the GPU (cuda_training_step.h), and
  // so does that built-in ADC (a strategy passed in runs on the host).
  Trainer(const TrainerOptions& options, const TrainingViews& views,
          std::vector<size_t> train_views, GaussianModel initial,
          double scene_extent, std::unique_ptr<Rasterizer> rasterizer,
          std::unique_ptr<DensityStrategy> strategy = nullptr);
  ~Trainer();

  // Restores the state of a checkpoint written by a run with the same
  // options; keeps the log lines up to its iteration. Throws Error.
  void Resume(const std::string& checkpoint_path);
  // One training iteration. Throws Error if the loss is not finite (the last
  // checkpoint is kept).
  IterationStats Step();
  // Steps until options.iterations, writing log, checkpoints and progress.
  void Run();

  TrainingCheckpoint MakeCheckpoint() const;
  void SaveCheckpoint(const std::string& path);
  // Rewrites the log file with every line so far (atomically).
  void FlushLog();

  // On the GPU path these copy the device state to the host first (only
  // when it moved on), and the mutable ones send host edits back before the
  // next step; a reference is current until the next Step.
  const GaussianModel& model() const;
  GaussianModel& mutable_model();
  Adam& adam();
  // Makes the host model and Adam current (GPU path; no-op on the CPU).
  void SyncToHost() const;
  // Trains through the device step `make` builds from now on (the trainer
  // does this itself for a CudaRasterizer; tests pass a host emulation).
  // With the built-in Inria strategy the step takes density control over
  // when it can; a strategy passed in stays on the host.
  void UseDeviceStep(const DeviceTrainingStepFactory& make);
  Rasterizer& rasterizer() { return *rasterizer_; }
  int64_t iteration() const { return iteration_; }
  int active_sh_degree() const { return active_sh_degree_; }
  // JSON lines logged so far (also written to log_path).
  const std::vector<std::string>& log_lines() const { return log_lines_; }
  double elapsed_seconds() const { return elapsed_seconds_; }
  // Training-state bytes per Gaussian: parameters, Adam moments, gradients
  // and density statistics (render contexts excluded).
  size_t StateBytesPerGaussian() const;

 private:
  size_t NextView();
  std::string RunSignature() const;
  void AppendLog(const IterationStats& stats, const EvalResult* test);
  [[noreturn]] void FailNonFiniteLoss(int64_t it, double loss, size_t view);
  [[noreturn]] void FailAllPruned(int64_t it);
  // Step's device path from the render on, for view `view` at iteration
  // `it`.
  IterationStats StepOnDevice(int64_t it, size_t view,
                              const RenderCamera& camera,
                              const RenderOptions& render_options,
                              const ImageRGB& truth);
  // StepOnDevice's density stage through the host strategy: statistics
  // from grads_ and radii_, model and moments synced both ways on the
  // iterations it may change them.
  DensityEvent HostDensityStep(int64_t it, bool wants_radii);

  TrainerOptions options_;
  const TrainingViews& views_;
  std::vector<size_t> train_views_;
  GaussianModel model_;
  double scene_extent_;
  std::unique_ptr<Rasterizer> rasterizer_;
  std::unique_ptr<DensityStrategy> strategy_;
  // The seeded options of strategy_ when the trainer built it (Inria's
  // ADC): only then may a device step take density control over.
  std::unique_ptr<DensityOptions> builtin_density_;
  // The device step runs density control (strategy_ is then idle and its
  // state stale; the device's is the run's).
  bool device_density_ = false;
  Adam adam_;
  // The device step mirroring model_ and adam_ (null on the host path).
  std::unique_ptr<DeviceTrainingStep> device_;
  TrainingLoss loss_;
  std::mt19937_64 rng_;
  // Views not yet drawn in the current epoch.
  std::vector<uint32_t> view_stack_;
  int64_t iteration_ = 0;
  int active_sh_degree_ = 0;
  double elapsed_seconds_ = 0;
  std::string last_checkpoint_;
  int64_t last_checkpoint_iteration_ = -1;
  std::vector<std::string> log_lines_;
  // Reused per-iteration buffers.
  ImageRGB render_, grad_image_;
  GaussianGradients grads_;
  std::vector<float> radii_;
};

}  // namespace watergs
