// WATER-GS watermark embedding (paper, Algorithm 1): fine-tunes a trained
// 3DGS model so that the frozen decoder reads the owner's message from its
// renders. Per iteration: a training view, one sampled 3D distortion layer N,
// a render of N(Θ) (a random crop when the decoder term suffices), the loss
// (1 - β) L1 + β (1 - SSIM) + γ BCE(m, D(render)), gradients back through the
// decoder's input gradient, the rasterizer and the distortion's scatter, then
// Adam restricted to the mask's parameter groups and (optionally) adaptive
// density control. Composes gaussian/ pieces; knows nothing of COLMAP.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "distortion/distortion_layer.h"
#include "gaussian/adam.h"
#include "gaussian/density_strategy.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder.h"
#include "watermark/device_embedding_step.h"
#include "watermark/distortion_choice.h"
#include "watermark/fidelity_budget.h"
#include "watermark/message.h"
#include "watermark/message_loss.h"
#include "watermark/view_jitter.h"
#include "watermark/viewpoint_pool.h"

namespace watergs {

// Parses "ALL" or a comma list of xyz,f_dc,f_rest,opacity,scaling,rotation
// into one trainable flag per ParamGroup; throws Error on unknown names.
std::array<bool, kNumParamGroups> ParseParamMask(const std::string& text);

struct EmbedOptions {
  // Fine-tuning iterations (paper: 10k to 30k).
  int64_t iterations = 10000;
  // Weight of the message loss (paper: 0.3; 0.1 for forward-facing scenes).
  double gamma = 0.3;
  // Weight of D-SSIM in the image loss.
  double beta = 0.2;
  // Trainable parameter groups (ParamGroup order); frozen ones stay
  // bit-identical.
  std::array<bool, kNumParamGroups> trainable = {true, true, true,
                                                 true, true, true};
  // Distortion layers sampled per iteration; empty = none (plain render).
  std::vector<DistortionSpec> distortions;
  // Chosen per scene: `distortions` are then candidates, none simulated at
  // first; at each check where every check view reads past the margin, each
  // candidate is reviewed on the check cameras and simulated from then on
  // once it falls short at two reviews in a row (distortion_choice.h).
  bool choose_distortions = false;
  // Side of the random square crop rendered per iteration (clamped to the
  // frame); 0 renders whole frames.
  int crop_size = 128;
  // Render the whole frame for the image loss and give the decoder only the
  // crop (instead of rendering just the crop for both terms).
  bool full_frame_image_loss = false;
  // Fraction of iterations rendered from a free viewpoint (between two
  // training cameras, as extract --num_views samples them) with the input
  // model's render there as the image target: the message then holds in
  // views no training camera saw, at the input model's fidelity there.
  double free_view_fraction = 0;
  // > 0: a pool of this many free viewpoints (drawn once from the seed, apart
  // from check_free_views) that hard_view_fraction of the free-view
  // iterations replay, each in proportion to how far it still falls short of
  // reading every bit past the margin (scored at each check): the effort
  // goes where single views do not read yet (viewpoint_pool.h).
  int hard_views = 0;
  double hard_view_fraction = 0.5;
  // Free viewpoints interpolate towards one of the view's this many nearest
  // training cameras (by centre); 0: towards any training camera. Near
  // neighbours sample the capture path, where held-out photos lie.
  int free_view_neighbors = 0;
  // The decoder reads each render through a random shift and zoom (see
  // view_jitter.h); off by default.
  DecoderJitterOptions decoder_jitter;
  // 1-100: on a jpeg_fraction of the iterations the decoder reads the
  // render through a real JPEG round trip at this quality, its gradient
  // taken as the identity (straight-through, as MBRS and StegaStamp train
  // for JPEG): the message learns to survive the screenshots a leak is
  // saved as. 0: off.
  int jpeg_quality = 0;
  double jpeg_fraction = 0;
  // The message term pushes each logit past +-margin (BCE on the logit
  // moved by the margin towards the wrong side): a view whose logits sit
  // far from 0 keeps its bits in the next, unseen view.
  double margin = 0;
  // The owner's reading: the message term (and the checks) read each bit
  // from logit(render) - logit(input model's render) at the same viewpoint
  // and patch, as `extract --raw_path` reads it; the scene's own lean per
  // bit then costs nothing to overcome. Needs no decoder jitter.
  bool owner_reading = false;
  // With owner_reading, a blind term beside it (weight > 0): the message
  // term also pushes the logits themselves past blind.margin, so that a
  // reader without the raw model finds the message too (--reading both).
  BlindTerm blind;
  // target_db > 0: blind.weight is steered at every check towards renders
  // that sit target_db from the input model's (fidelity_budget.h).
  FidelityBudget budget;
  // The image term's target on training cameras: the input model's render
  // there instead of the photo (free viewpoints always use the render), so
  // fine-tuning spends its changes on the message, not on refitting photos.
  bool fidelity_to_input = false;
  // > 0: the image term is mse_weight * mean squared error (PSNR's own
  // measure) instead of (1 - beta) L1 + beta D-SSIM.
  double mse_weight = 0;
  // > 0 (with mse_weight): texture masking of that term. Each pixel's
  // squared error is weighted by 1 / (1 + sigma / masking), sigma the local
  // standard deviation of the target's luminance (texture_masking.h):
  // changes cost less where the image is textured, as a JND model puts them
  // (HiDDeN+JND, Watson).
  double masking = 0;
  // BER over the check views is evaluated every check_every iterations;
  // fine-tuning stops after `patience` consecutive checks at BER 0 (0 = never
  // stop early).
  int64_t check_every = 200;
  int patience = 2;
  // > 0: stop at the first check where every bit of every check view and
  // free viewpoint reads at least this far past zero: the scene reads, and
  // more strength would only cost pixels.
  double stop_margin = 0;
  // Views (indices into the source) decoded at each check (whole frames).
  std::vector<size_t> check_views;
  // Free viewpoints decoded at each check too (no ground truth): early
  // stopping then waits for views no iteration rendered.
  std::vector<RenderCamera> check_free_views;
  // Adaptive density control during fine-tuning (as in training). Needs
  // every group trainable: new Gaussians change every group, so the
  // constructor refuses it with a partial mask.
  bool densify = true;
  DensityOptions density;
  // Optimiser rates; positions decay from position_lr_init to _final over
  // the run (a converged model needs only small moves).
  AdamOptions adam;
  // Seeds views, crops, distortions and density control.
  uint64_t seed = 0;
  // Colour behind the Gaussians and the SH degree used.
  std::array<float, 3> background = {0.f, 0.f, 0.f};
  // Checkpoint file and period (0 = only at the end if a path is given).
  std::string checkpoint_path;
  int64_t checkpoint_every = 0;
  // Draw a progress bar on stderr.
  bool show_progress = false;
};

// Defaults for fine-tuning: Inria's rates with the position rate starting
// where training ended, density control from iteration 100 to half the run
// without opacity resets (a reset would erase the scene being marked).
EmbedOptions DefaultEmbedOptions(int64_t iterations);

// Seconds of one iteration per stage.
struct EmbedTimings {
  double distortion = 0, render = 0, image_loss = 0, decoder = 0, backward = 0,
         density = 0, adam = 0;
  double Total() const {
    return distortion + render + image_loss + decoder + backward + density +
           adam;
  }
  void Add(const EmbedTimings& o);
};

// Figures of one iteration.
struct EmbedStepStats {
  int64_t iteration = 0;
  // Image loss terms of the rendered region and the BCE of the message.
  LossTerms image;
  double bce = 0;
  // Total loss and bit errors of this iteration's decoded render.
  double total = 0;
  int bit_errors = 0;
  // Name of the distortion layer used ("none" without layers).
  std::string distortion;
  size_t num_gaussians = 0;
  EmbedTimings timings;
};

// Result of decoding whole-frame renders of some views.
struct CheckResult {
  // Mean over views of each view's bit error rate.
  double mean_ber = 0;
  // The same over the free check viewpoints (0 without them).
  double free_mean_ber = 0;
  // Bit error rate of the mean logits over the views.
  double aggregate_ber = 0;
  // Mean PSNR of the renders against ground truth.
  double psnr = 0;
  // Mean PSNR against the input model's renders, over the check views and
  // the free viewpoints (what --target_psnr steers).
  double psnr_vs_input = 0;
  // The smallest signed logit (in the reading the embedding optimises) over
  // every bit of every check view and free viewpoint: > 0 when all read.
  double weakest_margin = std::numeric_limits<double>::infinity();
  // Each camera's logits in that reading: the views, then the free ones.
  std::vector<std::vector<float>> logits;
};

class Embedder {
 public:
  // `views` (outliving the embedder) supplies cameras and images;
  // `train_views` index into it. `decoder` is used frozen and must read
  // message.size() bits.
  Embedder(const EmbedOptions& options, const TrainingViews& views,
           std::vector<size_t> train_views, GaussianModel model,
           double scene_extent, BitDecoder* decoder, Bits message,
           std::unique_ptr<Rasterizer> rasterizer);
  ~Embedder();
  // Runs the iterations on the step `make` returns from now on (tests: a
  // host emulation of a device; the constructor picks the CUDA step).
  void UseDeviceStep(const DeviceEmbeddingStepFactory& make);

  // One fine-tuning iteration. Throws Error on a non-finite loss.
  EmbedStepStats Step();
  // Steps until options.iterations or early stop; writes checkpoints and
  // progress. Returns true if it stopped early.
  bool Run();
  // Decodes whole-frame renders of `views` and of the free check views.
  CheckResult Check(const std::vector<size_t>& views);

  // Restores a checkpoint written by a run with the same options.
  void Resume(const std::string& path);
  void SaveCheckpoint(const std::string& path) const;

  const GaussianModel& model() const;
  // For each Gaussian now, the index of the input Gaussian it descends from.
  const std::vector<int64_t>& origin() const { return origin_; }
  int64_t iteration() const { return iteration_; }
  // The blind term's weight now (options.blind.weight unless a budget
  // steers it).
  double blind_weight() const { return blind_.weight; }
  // The per-scene choice of layers (null unless choose_distortions).
  const DistortionChoice* distortion_choice() const { return choice_.get(); }
  // Sum of per-stage seconds over all iterations so far.
  const EmbedTimings& total_timings() const { return total_timings_; }
  // Seconds spent in Run's checks (with their distortion reviews) since
  // this process started, and how many ran: what --check_every costs.
  double check_seconds() const { return check_seconds_; }
  int64_t num_checks() const { return num_checks_; }
  Rasterizer& rasterizer() { return *rasterizer_; }
  // True when the iterations run on the GPU with the model resident there
  // (a CUDA rasterizer and decoder, float32 moments).
  bool device_resident() const { return device_ != nullptr; }
  // With a CUDA rasterizer and decoder but host steps: the option that keeps
  // the step on the host (empty otherwise).
  const std::string& host_step_reason() const { return host_step_reason_; }

 private:
  // What one iteration renders and decodes (drawn from rng_ by Step).
  struct IterationPlan {
    size_t view = 0;
    RenderCamera camera;
    std::shared_ptr<const ImageRGB> truth;
    // The sampled crop, and the render / decoder regions it sets.
    PixelRect crop;
    RenderOptions render_options;
    PixelRect decoder_crop;
    // Null without distortion layers.
    const DistortionLayer* layer = nullptr;
    // Applied to the (cropped) render before decoding, if jitter is on.
    JitterSample jitter;
    // A viewpoint between two cameras (truth is then the input's render).
    bool free_view = false;
    // The decoder reads the render through JPEG (options.jpeg_quality).
    bool jpeg = false;
    // Index into the hard-viewpoint pool (-1: not a pool view).
    int pool_view = -1;
    // The input model's logits of the decoded patch (owner's reading).
    std::shared_ptr<const std::vector<float>> reference_logits;
  };

  std::string RunSignature() const;
  size_t NextView();
  // A free viewpoint between two training cameras (or a pool view) and the
  // input model's render there (the image target).
  void PlanFreeView(IterationPlan* plan);
  // Renders the model being embedded (host or device) from `camera`,
  // clamped to [0, 1].
  void RenderCurrent(const RenderCamera& camera, ImageRGB* image);
  // The input model's render and logits at pool view k (cached).
  std::shared_ptr<const ImageRGB> PoolTarget(size_t k);
  std::shared_ptr<const std::vector<float>> PoolReferenceLogits(size_t k);
  // Decodes every pool view and records how far each falls short.
  void ScorePool();
  // The cameras Check(views) reads: `views`, then the free check viewpoints.
  std::vector<RenderCamera> CheckCameras(
      const std::vector<size_t>& views) const;
  // The input model's logits at CheckCameras(views) for the owner's reading
  // (empty without it); kept for the last view set asked.
  const std::vector<std::vector<float>>& CheckReference(
      const std::vector<size_t>& views);
  // The decoder's logits (in the optimised reading) of whole-frame renders
  // of `model` (null: the model being embedded) from `cameras`; `reference`
  // holds the input model's logits there for the owner's reading. Adds the
  // PSNR of render k against (*truths)[k] / truths->size() into *psnr.
  std::vector<std::vector<float>> ReadCameras(
      const GaussianModel* model, const std::vector<RenderCamera>& cameras,
      const std::vector<std::vector<float>>& reference,
      const std::vector<std::shared_ptr<const ImageRGB>>* truths = nullptr,
      double* psnr = nullptr,
      const std::vector<std::shared_ptr<const ImageRGB>>* inputs = nullptr,
      double* psnr_vs_input = nullptr);
  // The input model's renders at CheckCameras(views) (empty without an
  // input model); kept for the last view set asked.
  const std::vector<std::shared_ptr<const ImageRGB>>& CheckInputs(
      const std::vector<size_t>& views);
  // Reviews each candidate layer on the check cameras (choose_distortions),
  // `check` being the plain reading there now; true when one was turned on.
  bool ReviewDistortions(const CheckResult& check);
  // The input model's render from `camera`, clamped to [0, 1].
  std::shared_ptr<const ImageRGB> RenderInput(const RenderCamera& camera);
  // The input model's render from a training view (cached).
  std::shared_ptr<const ImageRGB> InputRender(size_t view);
  // The input model's logits of the patch `plan` decodes (cached for whole
  // frames of training views).
  std::shared_ptr<const std::vector<float>> ReferenceLogits(
      const IterationPlan& plan);
  // The image term of the options on `rendered` against `truth`.
  LossTerms ImageLoss(const ImageRGB& rendered, const ImageRGB& truth,
                      ImageRGB* grad);
  // Fills neighbors_ (free_view_neighbors > 0).
  void FindNeighbors();
  // The message term through the plan's jitter: adds its image gradient
  // into grad_image_ and returns the BCE.
  double JitteredMessageLoss(const IterationPlan& plan, EmbedStepStats* stats);
  // The message term read through a JPEG round trip of the decoded region;
  // its image gradient passes straight through to the render.
  double JpegMessageLoss(const IterationPlan& plan, EmbedStepStats* stats);
  PixelRect SampleRect(int width, int height);
  // The iteration's loss, backward, density control and Adam on the host
  // model, or on the device-resident one.
  DensityEvent HostIteration(int64_t it, const IterationPlan& plan,
                             EmbedStepStats* stats);
  DensityEvent DeviceIteration(int64_t it, const IterationPlan& plan,
                               EmbedStepStats* stats);
  // Error unless the iteration's loss is finite.
  void CheckLossFinite(int64_t it, const IterationPlan& plan,
                       const EmbedStepStats& stats) const;
  // Brings the host model and Adam up to date with the device's.
  void SyncToHost() const;

  EmbedOptions options_;
  const TrainingViews& views_;
  std::vector<size_t> train_views_;
  // Per source view, its free_view_neighbors nearest training views.
  std::vector<std::vector<size_t>> neighbors_;
  GaussianModel model_;
  // The input model, kept when free-view iterations render targets from it.
  GaussianModel input_model_;
  std::vector<std::shared_ptr<const ImageRGB>> input_renders_;
  std::vector<std::shared_ptr<const std::vector<float>>> reference_logits_;
  // The same through the JPEG layer's round trip (jpeg_quality).
  std::vector<std::shared_ptr<const std::vector<float>>> jpeg_reference_logits_;
  // CheckReference's cache and the views it holds.
  std::vector<std::vector<float>> check_reference_;
  std::vector<size_t> check_reference_views_;
  // CheckInputs' cache and the views it holds.
  std::vector<std::shared_ptr<const ImageRGB>> check_inputs_;
  std::vector<size_t> check_inputs_views_;
  // The blind term as the loss uses it (its weight steered by the budget).
  BlindTerm blind_;
  // Hard-viewpoint replay (null when hard_views is 0), with its targets.
  std::unique_ptr<ViewpointPool> pool_;
  std::vector<std::shared_ptr<const ImageRGB>> pool_targets_;
  std::vector<std::shared_ptr<const std::vector<float>>> pool_logits_;
  double scene_extent_;
  BitDecoder* decoder_;
  Bits message_;
  std::vector<float> targets_;
  std::unique_ptr<Rasterizer> rasterizer_;
  std::unique_ptr<DistortionSampler> sampler_;
  std::unique_ptr<DistortionChoice> choice_;
  std::unique_ptr<DensityStrategy> strategy_;
  // Density options with the run's seed (the strategy's).
  DensityOptions density_options_;
  Adam adam_;
  TrainingLoss loss_;
  std::mt19937_64 rng_;
  std::vector<int64_t> origin_;
  int64_t iteration_ = 0;
  int zero_ber_checks_ = 0;
  EmbedTimings total_timings_;
  double check_seconds_ = 0;
  int64_t num_checks_ = 0;
  // Reused per-iteration buffers.
  GaussianModel distorted_;
  std::vector<uint32_t> source_;
  ImageRGB render_, truth_crop_, grad_image_;
  // The decoder's region of the render, its jittered copy and gradient.
  ImageRGB decoder_region_, jittered_, grad_jittered_;
  GaussianGradients grads_, distorted_grads_;
  std::vector<float> radii_;
  // The device-resident step (null: iterations run on the host model), and
  // whether it took over density control.
  std::unique_ptr<DeviceEmbeddingStep> device_;
  std::string host_step_reason_;
  bool device_density_ = false;
};

// A crop_size x crop_size square (clamped to the frame) at a uniformly
// random position in a width x height frame.
PixelRect RandomCrop(int crop_size, int width, int height,
                     std::mt19937_64* rng);

// `embed --crop_size auto`: whole frames up to kAutoCropMaxFramePixels (every
// frame the project's tables use, fern's 504x378 among them); above it a
// random kAutoCropSide square, so that an iteration's render, decoder and
// backward pass stop growing with the frame (1M Gaussians at 1 MP within the
// hour: results/embed_1m/README.md).
constexpr int kAutoCropMaxFramePixels = 512 * 512;
constexpr int kAutoCropSide = 384;
// The crop side auto picks for frames of at most `max_frame_pixels` pixels
// (0: whole frames).
int AutoCropSize(int64_t max_frame_pixels);

}  // namespace watergs
