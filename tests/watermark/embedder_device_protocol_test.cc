// The embedder's device-resident path (device_embedding_step.h) checked
// without a GPU: a host emulation of the device step keeps its own model,
// Adam and density strategy ("device memory"), runs the CPU rasterizer,
// layers and decoder on them, and counts the mirror's transfers. An
// embedder driving it must give the host embedder's run bit for bit (same
// RNG draws, same density decisions, same origins, same checkpoints) and
// move the model only where the protocol says: up at the start and after a
// resume, down for checks, checkpoints and model().
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include "gaussian/checkpoint.h"
#include "gaussian/cpu_rasterizer.h"
#include "gaussian/projection.h"
#include "tests/common/embed_scene.h"
#include "watermark/device_embedding_step.h"
#include "watermark/embedder.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

// Transfers of the emulated device (the model and Adam each way).
struct Transfers {
  int pulls = 0, pushes = 0, density_changes = 0;
};

class EmulatedEmbeddingStep : public DeviceEmbeddingStep {
 public:
  EmulatedEmbeddingStep(const EmbedOptions& o, double extent,
                        BitDecoder* decoder, std::vector<float> targets,
                        GaussianModel* host_model, Adam* host_adam,
                        Transfers* transfers)
      : options_(o),
        decoder_(decoder),
        targets_(std::move(targets)),
        host_model_(host_model),
        host_adam_(host_adam),
        adam_(o.adam, extent),
        loss_(o.beta),
        rasterizer_(MakeCpuRasterizer()),
        transfers_(transfers) {}

  void TakeDensityControl(const DensityOptions& options, double extent,
                          const std::string& state) override {
    strategy_ = MakeInriaDensityStrategy(options, extent);
    LoadDensityState(state);
  }
  DeviceEmbedLoss Forward(const DeviceEmbedView& view,
                          std::mt19937_64& rng) override {
    PushIfStale();
    distort_ = view.layer && !view.layer->IsIdentity();
    if (distort_) view.layer->Apply(model_, rng, &distorted_, &source_);
    camera_ = view.camera;
    rasterizer_->Forward(distort_ ? distorted_ : model_, view.camera,
                         view.options, &render_, &context_);
    DeviceEmbedLoss out;
    out.image = loss_.Evaluate(render_, *view.truth, &grad_image_);
    out.bce = AddMessageLoss(*decoder_, render_, view.decoder_crop, targets_,
                             options_.gamma, &grad_image_, &out.bit_errors);
    return out;
  }
  DensityEvent BackwardAndUpdate(int64_t iteration, double*, double*,
                                 double*) override {
    if (distort_) {
      rasterizer_->Backward(distorted_, *context_, grad_image_, &dgrads_);
      ScatterGradients(dgrads_, source_, model_.size(), model_.sh_rest_stride(),
                       &grads_);
    } else {
      rasterizer_->Backward(model_, *context_, grad_image_, &grads_);
    }
    context_.reset();
    DensityEvent event;
    if (strategy_) {
      const std::vector<float>* radii = nullptr;
      if (strategy_->WantsRadii(iteration)) {
        ComputeScreenRadii(model_, camera_, grads_.visible, &radii_);
        radii = &radii_;
      }
      event =
          strategy_->PostBackward(iteration, grads_, radii, &model_, &adam_);
      if (event.densified || event.opacity_reset) {
        ++transfers_->density_changes;
      }
    }
    adam_.SetIteration(iteration);
    if (!event.densified) adam_.Step(grads_, &model_);
    host_stale_ = true;
    return event;
  }
  void Render(const RenderCamera& camera, const RenderOptions& options,
              ImageRGB* image) override {
    PushIfStale();
    rasterizer_->Forward(model_, camera, options, image, nullptr);
  }
  void PullModel() override {
    if (!host_stale_ || model_pulled_) return;
    *host_model_ = model_;
    model_pulled_ = true;
    ++transfers_->pulls;
  }
  // As CudaModelMirror: the host Adam is sized from the (pulled) host model
  // and takes the moments, step counts and rejected count.
  void PullAdam() override {
    if (!host_stale_ || adam_pulled_) return;
    PullModel();
    host_adam_->Init(*host_model_);
    for (int g = 0; g < kNumParamGroups; ++g) {
      const auto group = static_cast<ParamGroup>(g);
      host_adam_->state(group) = adam_.state(group);
    }
    host_adam_->set_rejected_total(adam_.rejected_total());
    adam_pulled_ = true;
    ++transfers_->pulls;
  }
  void MarkHostEdited() override { device_stale_ = true; }
  size_t NumGaussians() const override {
    return device_stale_ ? host_model_->size() : model_.size();
  }
  std::string SaveDensityState() const override {
    return strategy_->SaveState();
  }
  void LoadDensityState(const std::string& state) override {
    PushIfStale();
    strategy_->Init(model_);
    strategy_->LoadState(state);
  }

 private:
  void PushIfStale() {
    // A device step after a pull makes the host stale again.
    model_pulled_ = adam_pulled_ = false;
    if (!device_stale_) return;
    model_ = *host_model_;
    adam_ = *host_adam_;
    device_stale_ = host_stale_ = false;
    ++transfers_->pushes;
  }

  EmbedOptions options_;
  BitDecoder* decoder_;
  std::vector<float> targets_;
  GaussianModel* host_model_;
  Adam* host_adam_;
  // "Device memory".
  GaussianModel model_, distorted_;
  Adam adam_;
  std::unique_ptr<DensityStrategy> strategy_;
  TrainingLoss loss_;
  std::unique_ptr<Rasterizer> rasterizer_;
  // The current iteration's pass.
  bool distort_ = false;
  RenderCamera camera_;
  std::vector<uint32_t> source_;
  std::unique_ptr<RenderContext> context_;
  ImageRGB render_, grad_image_;
  GaussianGradients grads_, dgrads_;
  std::vector<float> radii_;
  // Mirror state: which side is behind, and whether the host caught up
  // since the last device step.
  bool device_stale_ = true, host_stale_ = false;
  bool model_pulled_ = false, adam_pulled_ = false;
  Transfers* transfers_;
};

struct Setup : testing::Scene {
  std::unique_ptr<HiddenModel> net;
  std::unique_ptr<Decoder> decoder;
  Bits message;
  EmbedOptions options;
};

// 3 views of a ball rendered from itself, a tiny random decoder, every
// layer kind, densification every 3 iterations from 2 with a low threshold
// (so it clones, splits and prunes), opacity resets every 7 (screen radii
// read from 8 on), checks every 4 iterations.
std::unique_ptr<Setup> MakeSetup(int iterations) {
  auto s = std::make_unique<Setup>();
  static_cast<testing::Scene&>(*s) = testing::MakeScene(3, 32, 24);
  s->net =
      std::make_unique<HiddenModel>(testing::TinyDecoderConfig(8), false, 3);
  s->decoder = std::make_unique<Decoder>(s->net.get());
  s->message = {1, 0, 1, 1, 0, 0, 1, 0};
  EmbedOptions& o = s->options;
  o = DefaultEmbedOptions(iterations);
  o.crop_size = 16;
  o.distortions = ParseDistortionList("identity,gn:0.01,dropout:0.2,crop:0.2");
  o.density.densify_from_iter = 2;
  o.density.densification_interval = 3;
  o.density.densify_until_iter = iterations;
  o.density.opacity_reset_interval = 7;
  o.density.grad_threshold = 1e-7;
  o.check_every = 4;
  o.patience = 0;
  o.check_views = {0};
  o.seed = 11;
  return s;
}

std::unique_ptr<Embedder> MakeEmbedder(const Setup& s) {
  return std::make_unique<Embedder>(s.options, s.views, s.train, s.model, 3.0,
                                    s.decoder.get(), s.message,
                                    MakeCpuRasterizer());
}

// Moves `e` onto an emulated device step counting into `t`.
void Emulate(Embedder* e, const Setup& s, Transfers* t) {
  const std::vector<float> targets(s.message.begin(), s.message.end());
  e->UseDeviceStep([&](GaussianModel* host_model, Adam* host_adam) {
    return std::make_unique<EmulatedEmbeddingStep>(
        s.options, 3.0, s.decoder.get(), targets, host_model, host_adam, t);
  });
}

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("watergs_embed_protocol_" + std::to_string(::getpid()) + name))
      .string();
}

void ExpectSameModel(const GaussianModel& a, const GaussianModel& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.means, b.means);
  EXPECT_EQ(a.log_scales, b.log_scales);
  EXPECT_EQ(a.quats, b.quats);
  EXPECT_EQ(a.opacity_logits, b.opacity_logits);
  EXPECT_EQ(a.sh_dc, b.sh_dc);
  EXPECT_EQ(a.sh_rest, b.sh_rest);
}

// 20 iterations with checks every 4 and checkpoints every 10: the model
// goes up once and comes down with the moments only for the two
// checkpoints (4 pulls): the checks render the device model, and the
// densifications happen on the device.
TEST(EmbedderDeviceProtocol, EmulatedDeviceRunEqualsTheHostRun) {
  auto s = MakeSetup(20);
  s->options.checkpoint_every = 10;
  s->options.checkpoint_path = TempPath("host.ckpt");
  auto host = MakeEmbedder(*s);
  host->Run();
  s->options.checkpoint_path = TempPath("device.ckpt");
  auto device = MakeEmbedder(*s);
  Transfers t;
  Emulate(device.get(), *s, &t);
  ASSERT_TRUE(device->device_resident());
  device->Run();
  EXPECT_EQ(t.pushes, 1);
  EXPECT_EQ(t.pulls, 4);
  EXPECT_GT(t.density_changes, 0);
  EXPECT_NE(host->model().size(), s->model.size());
  ExpectSameModel(host->model(), device->model());
  EXPECT_EQ(host->origin(), device->origin());
  // The checkpoints hold the same state (a stale host copy would not), the
  // device's density state written as the CPU strategy's bytes.
  const TrainingCheckpoint a = ReadCheckpoint(TempPath("host.ckpt"));
  const TrainingCheckpoint b = ReadCheckpoint(TempPath("device.ckpt"));
  std::filesystem::remove(TempPath("host.ckpt"));
  std::filesystem::remove(TempPath("device.ckpt"));
  EXPECT_EQ(a.iteration, 20);
  ExpectSameModel(a.model, b.model);
  for (int g = 0; g < kNumParamGroups; ++g) {
    EXPECT_EQ(a.adam[g].exp_avg_sq, b.adam[g].exp_avg_sq) << g;
    EXPECT_EQ(a.adam[g].step, b.adam[g].step) << g;
  }
  EXPECT_EQ(a.density_state, b.density_state);
  EXPECT_EQ(a.rng_state, b.rng_state);
}

// A checkpoint moves between the host and the device path both ways, and
// each resumed run ends where the uninterrupted host run ends.
TEST(EmbedderDeviceProtocol, CheckpointsResumeAcrossHostAndDevice) {
  const auto s = MakeSetup(20);
  auto whole = MakeEmbedder(*s);
  for (int i = 0; i < 20; ++i) whole->Step();
  for (bool first_on_device : {false, true}) {
    SCOPED_TRACE(first_on_device ? "device -> host" : "host -> device");
    const std::string path = TempPath("half.ckpt");
    Transfers t;
    {
      auto first = MakeEmbedder(*s);
      if (first_on_device) Emulate(first.get(), *s, &t);
      for (int i = 0; i < 10; ++i) first->Step();
      first->SaveCheckpoint(path);
    }
    auto second = MakeEmbedder(*s);
    if (!first_on_device) Emulate(second.get(), *s, &t);
    second->Resume(path);
    std::filesystem::remove(path);
    for (int i = 0; i < 10; ++i) second->Step();
    EXPECT_EQ(second->iteration(), 20);
    ExpectSameModel(whole->model(), second->model());
    EXPECT_EQ(whole->origin(), second->origin());
    EXPECT_GT(t.density_changes, 0);
  }
}

// Leaving the device mid-run (after it densified) hands the model, the
// moments (re-sized to the device's Gaussians) and the density state back
// to the host, which continues the same run.
TEST(EmbedderDeviceProtocol, HostContinuesARunTheDeviceStarted) {
  const auto s = MakeSetup(20);
  auto whole = MakeEmbedder(*s);
  for (int i = 0; i < 20; ++i) whole->Step();
  auto moved = MakeEmbedder(*s);
  Transfers t;
  Emulate(moved.get(), *s, &t);
  for (int i = 0; i < 10; ++i) moved->Step();
  ASSERT_GT(t.density_changes, 0);
  moved->UseDeviceStep([](GaussianModel*, Adam*) { return nullptr; });
  ASSERT_FALSE(moved->device_resident());
  for (int i = 0; i < 10; ++i) moved->Step();
  ExpectSameModel(whole->model(), moved->model());
  EXPECT_EQ(whole->origin(), moved->origin());
}

}  // namespace
}  // namespace watergs
