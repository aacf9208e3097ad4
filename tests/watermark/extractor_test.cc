// Tests of watermark extraction: aggregation over views, the statistics
// reported, free viewpoints, and that an unmarked model is not claimed.
#include "watermark/extractor.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "gaussian/util/error.h"
#include "tests/common/look_at.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

GaussianModel RandomBall(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianModel m;
  m.sh_degree = 0;
  m.Resize(n);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      m.means[3 * i + a] = 0.8f * u(rng);
      m.log_scales[3 * i + a] = std::log(0.12f * (1.2f + 0.5f * u(rng)));
      m.sh_dc[3 * i + a] = 1.2f * u(rng);
    }
    m.quats[4 * i] = 1;
    m.opacity_logits[i] = 1.0f + u(rng);
  }
  return m;
}

struct ExtractScene {
  InMemoryViews views;
  std::vector<RenderCamera> cameras;
  std::vector<std::string> names;
  GaussianModel model = RandomBall(60, 3);
  HiddenModel net;
  ExtractScene() : net(Config(), false, 21) {
    for (int v = 0; v < 5; ++v) {
      const double a = 2 * M_PI * v / 5;
      cameras.push_back(LookAtOrigin(
          Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 32, 24));
      names.push_back("v" + std::to_string(v));
      views.Add(names.back(), cameras.back(), ImageRGB(32, 24));
    }
  }
  static HiddenConfig Config() {
    HiddenConfig c;
    c.num_bits = 48;
    c.channels = 6;
    c.decoder_blocks = 2;
    c.encoder_blocks = 1;
    return c;
  }
};

TEST(Extractor, AggregatesLogitsAndReportsSpreadAndPValue) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  Bits expected(48);
  for (int i = 0; i < 48; ++i) expected[i] = (i * 7) % 3 == 0;
  const ExtractionResult r =
      ExtractWatermark(*rasterizer, s.model, s.cameras, s.names, decoder,
                       &expected, {0, 0, 0}, VerificationThresholds{});
  ASSERT_EQ(r.views.size(), 5u);
  // Recompute the aggregate independently from per-view renders.
  std::vector<double> sum(48, 0);
  std::vector<double> bers;
  for (size_t v = 0; v < s.cameras.size(); ++v) {
    ImageRGB image;
    rasterizer->Forward(s.model, s.cameras[v], RenderOptions{}, &image,
                        nullptr);
    for (float& x : image.data) x = std::clamp(x, 0.f, 1.f);
    const std::vector<float> logits = decoder.Logits(image);
    int errors = 0;
    for (int i = 0; i < 48; ++i) {
      sum[i] += logits[i];
      errors += (logits[i] > 0) != (expected[i] == 1);
    }
    bers.push_back(errors / 48.0);
    EXPECT_EQ(r.views[v].bit_errors, errors);
  }
  int errors = 0;
  for (int i = 0; i < 48; ++i) {
    EXPECT_EQ(r.recovered[i], sum[i] > 0 ? 1 : 0) << i;
    errors += r.recovered[i] != expected[i];
  }
  EXPECT_EQ(r.bit_errors, errors);
  std::sort(bers.begin(), bers.end());
  EXPECT_DOUBLE_EQ(r.min_view_ber, bers.front());
  EXPECT_DOUBLE_EQ(r.median_view_ber, bers[2]);
  EXPECT_DOUBLE_EQ(r.max_view_ber, bers.back());
  EXPECT_DOUBLE_EQ(r.p_value, BinomialTailPValue(48 - errors, 48));
  const auto j = nlohmann::json::parse(ExtractionToJson(r));
  EXPECT_EQ(j["bit_errors"], errors);
  EXPECT_EQ(j["recovered_bits"], BitsToString(r.recovered));
}

// An image attack that halves every value: it moves the decoder's logits.
ImageRGB Darken(const ImageRGB& image) {
  ImageRGB out = image;
  for (float& v : out.data) v *= 0.5f;
  return out;
}

// The observer sees, once a camera and in order, exactly the image that was
// decoded: the clamped render after the attack (eval's PSNR column reads
// these instead of rendering each view again).
TEST(Extractor, ObserverSeesEachDecodedImageAfterTheAttack) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  std::vector<size_t> order;
  std::vector<ImageRGB> seen;
  const ExtractionResult r =
      ExtractWatermark(*rasterizer, s.model, s.cameras, s.names, decoder,
                       nullptr, {0, 0, 0}, VerificationThresholds{}, Darken,
                       [&](size_t camera, const ImageRGB& decoded) {
                         order.push_back(camera);
                         seen.push_back(decoded);
                       });
  ASSERT_EQ(seen.size(), s.cameras.size());
  for (size_t v = 0; v < s.cameras.size(); ++v) {
    EXPECT_EQ(order[v], v);
    ImageRGB image;
    rasterizer->Forward(s.model, s.cameras[v], RenderOptions{}, &image,
                        nullptr);
    for (float& x : image.data) x = std::clamp(x, 0.f, 1.f);
    const ImageRGB expected = Darken(image);
    ASSERT_EQ(seen[v].data.size(), expected.data.size());
    for (size_t i = 0; i < expected.data.size(); ++i) {
      ASSERT_FLOAT_EQ(seen[v].data[i], expected.data[i]) << v << " " << i;
    }
    EXPECT_EQ(decoder.Logits(seen[v]), r.views[v].logits) << v;
  }
}

// An unmarked model tested against many claimed messages: the verdict is
// never "present" (its false-positive rate is 1e-6 per claim).
TEST(Extractor, RawModelDoesNotClaimTheWatermark) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  std::mt19937 rng(4);
  for (int trial = 0; trial < 10; ++trial) {
    Bits claimed(48);
    for (auto& b : claimed) b = rng() & 1;
    const ExtractionResult r =
        ExtractWatermark(*rasterizer, s.model, s.cameras, s.names, decoder,
                         &claimed, {0, 0, 0}, VerificationThresholds{});
    EXPECT_NE(r.verdict, Verdict::kPresent) << "trial " << trial;
    EXPECT_GT(r.p_value, 1e-6);
  }
}

// The owner's reading is the blind aggregation applied to suspect minus
// reference logits per view, recomputed here from renders of both models;
// the blind result of the same call equals ExtractWatermark's.
TEST(Extractor, OwnerReadingDecodesTheDifferenceFromTheReference) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  GaussianModel suspect = s.model;
  for (float& c : suspect.sh_dc) c += 0.3f;
  Bits expected(48);
  for (int i = 0; i < 48; ++i) expected[i] = (i * 5) % 3 == 0;
  const OwnerExtraction both = ExtractWatermarkWithReference(
      *rasterizer, suspect, s.model, s.cameras, s.names, decoder, &expected,
      {0, 0, 0}, VerificationThresholds{});
  const ExtractionResult blind =
      ExtractWatermark(*rasterizer, suspect, s.cameras, s.names, decoder,
                       &expected, {0, 0, 0}, VerificationThresholds{});
  EXPECT_EQ(both.blind.recovered, blind.recovered);
  EXPECT_EQ(both.blind.bit_errors, blind.bit_errors);
  ASSERT_EQ(both.owner.views.size(), s.cameras.size());
  std::vector<double> sum(48, 0);
  for (size_t v = 0; v < s.cameras.size(); ++v) {
    ImageRGB a, b;
    rasterizer->Forward(suspect, s.cameras[v], RenderOptions{}, &a, nullptr);
    rasterizer->Forward(s.model, s.cameras[v], RenderOptions{}, &b, nullptr);
    for (float& x : a.data) x = std::clamp(x, 0.f, 1.f);
    for (float& x : b.data) x = std::clamp(x, 0.f, 1.f);
    const std::vector<float> la = decoder.Logits(a), lb = decoder.Logits(b);
    int errors = 0;
    for (int i = 0; i < 48; ++i) {
      const double d = double(la[i]) - lb[i];
      if (std::abs(d) <= kOwnerTieLogit) {
        // A tie reads against the claim.
        EXPECT_EQ(both.owner.views[v].logits[i],
                  expected[i] ? -kOwnerTieLogit : kOwnerTieLogit);
        sum[i] += both.owner.views[v].logits[i];
        ++errors;
        continue;
      }
      EXPECT_NEAR(both.owner.views[v].logits[i], d, 1e-5) << v << " " << i;
      sum[i] += d;
      errors += (d > 0) != (expected[i] == 1);
    }
    EXPECT_EQ(both.owner.views[v].bit_errors, errors) << v;
  }
  for (int i = 0; i < 48; ++i) {
    EXPECT_EQ(both.owner.recovered[i], sum[i] > 0 ? 1 : 0) << i;
  }
  // Not the blind read: the reference's lean is gone.
  EXPECT_NE(both.owner.mean_logits, both.blind.mean_logits);
}

// The raw model read as the owner against itself: every difference is a tie,
// which reads against the claim whatever the claim: BER 100%, "absent".
TEST(Extractor, OwnerReadingOfTheReferenceItselfIsAbsent) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  std::mt19937 rng(8);
  for (int trial = 0; trial < 3; ++trial) {
    Bits claimed(48);
    for (auto& b : claimed) b = rng() & 1;
    const OwnerExtraction both = ExtractWatermarkWithReference(
        *rasterizer, s.model, s.model, s.cameras, s.names, decoder, &claimed,
        {0, 0, 0}, VerificationThresholds{});
    EXPECT_EQ(both.owner.bit_errors, 48);
    EXPECT_DOUBLE_EQ(both.owner.min_view_ber, 1.0);
    EXPECT_EQ(both.owner.verdict, Verdict::kAbsent);
  }
  // Without a claim a tie reads 0.
  std::vector<float> tie = {0.f, 5e-4f, -2.f};
  ResolveOwnerTies(&tie, nullptr);
  EXPECT_EQ(tie, (std::vector<float>{0.f, 0.f, -2.f}));
  std::vector<ViewDecode> one(1), none;
  EXPECT_THROW(DifferenceViews(one, none, nullptr), Error);
}

// Through an image attack the reference goes the suspect's way too: a
// suspect that is the reference reads every difference exactly 0 (with a
// clean reference the attack's own shift of the logits would remain).
TEST(Extractor, OwnerReadingSendsTheReferenceThroughTheSameAttack) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  const OwnerExtraction both = ExtractWatermarkWithReference(
      *rasterizer, s.model, s.model, s.cameras, s.names, decoder, nullptr,
      {0, 0, 0}, VerificationThresholds{}, Darken);
  ASSERT_EQ(both.owner.views.size(), s.cameras.size());
  double largest_move = 0;
  for (size_t v = 0; v < s.cameras.size(); ++v) {
    for (float d : both.owner.views[v].logits) EXPECT_EQ(d, 0.f) << v;
    // The attack does move the logits, past the tie band that reads a small
    // difference as 0: a clean reference would leave a nonzero difference.
    const ExtractionResult clean =
        ExtractWatermark(*rasterizer, s.model, {s.cameras[v]}, {s.names[v]},
                         decoder, nullptr, {0, 0, 0}, VerificationThresholds{});
    for (size_t i = 0; i < clean.views[0].logits.size(); ++i) {
      largest_move =
          std::max(largest_move, double(std::abs(both.blind.views[v].logits[i] -
                                                 clean.views[0].logits[i])));
    }
  }
  EXPECT_GT(largest_move, 10 * kOwnerTieLogit);
}

TEST(Extractor, RefusesAnExpectedMessageOfTheWrongLength) {
  ExtractScene s;
  Decoder decoder(&s.net);
  auto rasterizer = MakeCpuRasterizer();
  const Bits short_message(40, 1);
  EXPECT_THROW(
      ExtractWatermark(*rasterizer, s.model, s.cameras, s.names, decoder,
                       &short_message, {0, 0, 0}, VerificationThresholds{}),
      Error);
}

TEST(Extractor, FreeViewpointsLieBetweenTheCameras) {
  ExtractScene s;
  const std::vector<RenderCamera> free = SampleFreeViewpoints(s.views, 12, 1);
  ASSERT_EQ(free.size(), 12u);
  for (const RenderCamera& cam : free) {
    EXPECT_NEAR(
        (cam.R * cam.R.transpose() - Eigen::Matrix3d::Identity()).norm(), 0,
        1e-9);
    EXPECT_NEAR(cam.R.determinant(), 1, 1e-9);
    // Cameras sit on a circle of radius 3 (height 0.5): chords lie inside.
    const Eigen::Vector3d c = cam.Center();
    EXPECT_LE(c.head<2>().norm(), 3 + 1e-9);
    EXPECT_NEAR(c.z(), 0.5, 1e-9);
    EXPECT_EQ(cam.width, 32);
  }
  const auto again = SampleFreeViewpoints(s.views, 12, 1);
  EXPECT_EQ(again[5].t, free[5].t);
}

}  // namespace
}  // namespace watergs
