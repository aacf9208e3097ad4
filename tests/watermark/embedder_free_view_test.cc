// Free-view iterations of the embedder (EmbedOptions::free_view_fraction):
// iterations rendered between two training cameras, with the input model's
// render there as the image target, carry the message to viewpoints no
// training camera saw; runs with them resume exactly; runs without them are
// unchanged (no extra random draw).
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "gaussian/checkpoint.h"
#include "gaussian/util/error.h"
#include "tests/common/embed_scene.h"
#include "watermark/embedder.h"
#include "watermark/extractor.h"
#include "watermark/feature_decoder.h"

namespace watergs {
namespace {

using testing::MakeScene;
using testing::RandomBits;
using testing::Scene;

// A tiny random-feature decoder whose logits are centred on the scene's
// training renders and scaled to be sensitive (as a calibrated one is).
std::unique_ptr<FeatureDecoder> TinyFeatureDecoder(const Scene& s, int bits) {
  auto net =
      std::make_unique<FeatureNet>(FeatureDecoderConfig{bits, 24, 2, 3}, 4);
  std::mt19937 rng(8);
  std::normal_distribution<float> normal(0.f, 30.f);
  for (float& w : net->linear.weight.value) w = normal(rng);
  auto decoder = std::make_unique<FeatureDecoder>(std::move(net));
  std::vector<double> mean(bits, 0.0);
  for (size_t v : s.train) {
    const std::vector<float> z = decoder->Logits(*s.views.Image(v));
    for (int b = 0; b < bits; ++b) mean[b] += z[b] / s.train.size();
  }
  for (int b = 0; b < bits; ++b) decoder->net().linear.bias.value[b] = -mean[b];
  return decoder;
}

double NovelViewBer(Embedder& embedder, const Scene& s, BitDecoder& decoder,
                    const Bits& message) {
  const std::vector<RenderCamera> cameras =
      SampleFreeViewpoints(s.views, 6, 99);
  const std::vector<std::string> names(cameras.size(), "free");
  const ExtractionResult r = ExtractWatermark(
      embedder.rasterizer(), embedder.model(), cameras, names, decoder,
      &message, {0, 0, 0}, VerificationThresholds{}, RenderAttack{});
  double ber = 0;
  for (const ViewDecode& v : r.views)
    ber += double(v.bit_errors) / message.size();
  return ber / r.views.size();
}

// An embedder of `s` with `o`, the tiny decoder and message 1 (the resume
// tests build three alike).
std::unique_ptr<Embedder> NewEmbedder(const EmbedOptions& o, const Scene& s,
                                      FeatureDecoder* decoder) {
  return std::make_unique<Embedder>(o, s.views, s.train, s.model, 3.0, decoder,
                                    RandomBits(8, 1), MakeCpuRasterizer());
}

// Steps a fresh embedder `steps` times, checkpoints it to `path` and resumes
// a new one from there (not yet run on).
std::unique_ptr<Embedder> ResumedAfter(int steps, const EmbedOptions& o,
                                       const Scene& s, FeatureDecoder* decoder,
                                       const std::string& path) {
  const std::unique_ptr<Embedder> first = NewEmbedder(o, s, decoder);
  for (int i = 0; i < steps; ++i) first->Step();
  first->SaveCheckpoint(path);
  std::unique_ptr<Embedder> resumed = NewEmbedder(o, s, decoder);
  resumed->Resume(path);
  return resumed;
}

EmbedOptions FreeViewOptions(int64_t iterations) {
  EmbedOptions o = DefaultEmbedOptions(iterations);
  o.crop_size = 0;
  o.gamma = 3;
  o.densify = false;
  o.adam.feature_lr = 0.02;
  o.free_view_fraction = 1.0;
  o.seed = 3;
  return o;
}

TEST(EmbedderFreeViews, CarryTheMessageToNovelViewpoints) {
  Scene s = MakeScene(6, 32, 24);
  std::unique_ptr<FeatureDecoder> decoder = TinyFeatureDecoder(s, 12);
  const Bits message = RandomBits(12, 5);
  // Only free viewpoints are rendered: no training camera is ever decoded.
  // The control is the same run without the message term.
  EmbedOptions o = FreeViewOptions(100);
  Embedder embedder(o, s.views, s.train, s.model, 3.0, decoder.get(), message,
                    MakeCpuRasterizer());
  o.gamma = 0;
  Embedder control(o, s.views, s.train, s.model, 3.0, decoder.get(), message,
                   MakeCpuRasterizer());
  const double before = NovelViewBer(embedder, s, *decoder, message);
  embedder.Run();
  control.Run();
  const double after = NovelViewBer(embedder, s, *decoder, message);
  const double after_control = NovelViewBer(control, s, *decoder, message);
  EXPECT_GT(before, 0.25);
  EXPECT_LT(after, before - 0.1);
  EXPECT_LT(after, after_control - 0.1);
}

TEST(EmbedderFreeViews, ResumeGivesTheSameResultAsAnUninterruptedRun) {
  Scene s = MakeScene(3, 24, 20);
  std::unique_ptr<FeatureDecoder> decoder = TinyFeatureDecoder(s, 8);
  EmbedOptions o = FreeViewOptions(6);
  o.free_view_fraction = 0.5;
  const std::string path = ::testing::TempDir() + "free_view_resume.ckpt";
  const std::unique_ptr<Embedder> full = NewEmbedder(o, s, decoder.get());
  full->Run();
  const std::unique_ptr<Embedder> resumed =
      ResumedAfter(3, o, s, decoder.get(), path);
  resumed->Run();
  EXPECT_EQ(resumed->model().sh_dc, full->model().sh_dc);
  EXPECT_EQ(resumed->model().means, full->model().means);
  // A run with another fraction does not take this checkpoint.
  o.free_view_fraction = 0.25;
  EXPECT_THROW(NewEmbedder(o, s, decoder.get())->Resume(path), Error);
  std::remove(path.c_str());
}

TEST(EmbedderFreeViews, HardViewpointRunsResumeExactly) {
  Scene s = MakeScene(3, 24, 20);
  std::unique_ptr<FeatureDecoder> decoder = TinyFeatureDecoder(s, 8);
  // Every iteration replays a pool view, and the pool is scored every 4
  // iterations: iterations 6-8 draw from the deficits the checkpoint at 5
  // carried.
  EmbedOptions o = FreeViewOptions(12);
  o.owner_reading = true;
  o.margin = 1;
  o.hard_views = 4;
  o.hard_view_fraction = 1;
  o.check_every = 4;
  const std::string path = ::testing::TempDir() + "hard_view_resume.ckpt";
  const std::unique_ptr<Embedder> full = NewEmbedder(o, s, decoder.get());
  full->Run();
  const std::unique_ptr<Embedder> resumed =
      ResumedAfter(5, o, s, decoder.get(), path);
  // The pool's deficits (measured at 4) come back with the rest.
  const std::string again = path + ".again";
  resumed->SaveCheckpoint(again);
  EXPECT_EQ(ReadCheckpoint(again).rng_state, ReadCheckpoint(path).rng_state);
  std::remove(again.c_str());
  resumed->Run();
  EXPECT_EQ(resumed->model().sh_dc, full->model().sh_dc);
  EXPECT_EQ(resumed->model().means, full->model().means);
  EXPECT_NE(full->model().sh_dc, s.model.sh_dc);
  // A run with another pool does not take this checkpoint.
  o.hard_views = 5;
  EXPECT_THROW(NewEmbedder(o, s, decoder.get())->Resume(path), Error);
  std::remove(path.c_str());
}

TEST(EmbedderFreeViews, HardViewsNeedFreeViewIterations) {
  Scene s = MakeScene(2, 16, 12);
  std::unique_ptr<FeatureDecoder> decoder = TinyFeatureDecoder(s, 8);
  EmbedOptions o = FreeViewOptions(2);
  o.hard_views = 4;
  o.free_view_fraction = 0;
  EXPECT_THROW(Embedder(o, s.views, s.train, s.model, 3.0, decoder.get(),
                        RandomBits(8, 1), MakeCpuRasterizer()),
               Error);
  o.free_view_fraction = 0.5;
  o.hard_view_fraction = 1.5;
  EXPECT_THROW(Embedder(o, s.views, s.train, s.model, 3.0, decoder.get(),
                        RandomBits(8, 1), MakeCpuRasterizer()),
               Error);
}

TEST(EmbedderFreeViews, RefusesAFractionOutsideZeroOne) {
  Scene s = MakeScene(2, 16, 12);
  std::unique_ptr<FeatureDecoder> decoder = TinyFeatureDecoder(s, 8);
  for (double fraction : {-0.1, 1.5, std::nan("")}) {
    EmbedOptions o = FreeViewOptions(2);
    o.free_view_fraction = fraction;
    EXPECT_THROW(Embedder(o, s.views, s.train, s.model, 3.0, decoder.get(),
                          RandomBits(8, 1), MakeCpuRasterizer()),
                 Error)
        << fraction;
  }
}

}  // namespace
}  // namespace watergs
