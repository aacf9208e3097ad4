// Tests of the file attacks: what each one promises about the model and its
// renders (SH truncation, float16 and k-bit quantisation, shuffle, similarity
// transform with moved cameras, opacity pruning) and the attack-list parser.
#include "distortion/file_attacks.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>

#include "gaussian/rasterizer.h"
#include "gaussian/sh.h"
#include "gaussian/util/error.h"
#include "tests/common/look_at.h"
#include "tests/common/random_model.h"

namespace watergs {
namespace {

// n random Gaussians in [-1, 1]^3 with degree-`sh_degree` colour, small
// enough and opaque enough that renders show every attribute.
GaussianModel RandomScene(size_t n, int sh_degree, uint64_t seed) {
  RandomModelRanges ranges;
  ranges.sh_rest = 0.4f;
  return RandomModel(n, sh_degree, seed, ranges);
}

ImageRGB Render(const GaussianModel& model, const RenderCamera& camera) {
  ImageRGB image;
  MakeCpuRasterizer()->Forward(model, camera, RenderOptions{}, &image, nullptr);
  return image;
}

RenderCamera TestCamera() {
  return LookAtOrigin(Eigen::Vector3d(3.0, -2.0, 1.5), 64, 48);
}

float MaxAbsDifference(const ImageRGB& a, const ImageRGB& b) {
  EXPECT_EQ(a.data.size(), b.data.size());
  float worst = 0.f;
  for (size_t i = 0; i < a.data.size(); ++i) {
    worst = std::max(worst, std::abs(a.data[i] - b.data[i]));
  }
  return worst;
}

GaussianModel Attacked(const std::string& attack, const GaussianModel& in,
                       std::vector<uint32_t>* source, uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  GaussianModel out;
  ApplyModelAttack(ParseModelAttack(attack), in, rng, &out, source);
  return out;
}

TEST(FileAttacks, ShTruncationRendersAsTheDegree0Model) {
  const GaussianModel in = RandomScene(300, 3, 1);
  std::vector<uint32_t> source;
  const GaussianModel truncated = Attacked("sh0", in, &source);
  EXPECT_EQ(truncated.sh_degree, 3);  // layout kept
  EXPECT_EQ(truncated.sh_rest.size(), in.sh_rest.size());
  GaussianModel degree0 = in;
  degree0.sh_degree = 0;
  degree0.sh_rest.clear();
  const RenderCamera camera = TestCamera();
  const ImageRGB a = Render(truncated, camera), b = Render(degree0, camera);
  EXPECT_EQ(a.data, b.data);
  // And the attack changed something: the original has view dependence.
  EXPECT_GT(MaxAbsDifference(a, Render(in, camera)), 0.01f);
}

TEST(FileAttacks, Float16RoundsToTheNearestHalf) {
  GaussianModel in = RandomScene(200, 1, 2);
  in.means[0] = 1e6f;   // beyond the float16 range
  in.means[1] = 1e-9f;  // below float16's smallest subnormal / 2
  std::vector<uint32_t> source;
  const GaussianModel out = Attacked("fp16", in, &source);
  EXPECT_EQ(out.means[0], 65504.f);
  EXPECT_EQ(out.means[1], 0.f);
  for (size_t i = 2; i < in.means.size(); ++i) {
    const float v = in.means[i], q = out.means[i];
    // Representable in float16 and within half a float16 ulp (2^-11
    // relative for normal values, 2^-25 absolute for subnormals).
    EXPECT_EQ(float(Eigen::half(q)), q);
    EXPECT_LE(std::abs(q - v), std::max(std::abs(v) * std::ldexp(1.f, -11),
                                        std::ldexp(1.f, -25)));
  }
  std::vector<uint32_t> again_source;
  EXPECT_EQ(Attacked("fp16", out, &again_source).sh_rest, out.sh_rest);
}

TEST(FileAttacks, LinearQuantisationErrorIsWithinHalfAStep) {
  const GaussianModel in = RandomScene(500, 2, 3);
  std::vector<uint32_t> source;
  const GaussianModel out = Attacked("quant:8", in, &source);
  const int stride = in.sh_rest_stride();
  for (int column = 0; column < stride; ++column) {
    double lo = 1e30, hi = -1e30;
    std::set<float> levels;
    for (size_t i = 0; i < in.size(); ++i) {
      lo = std::min<double>(lo, in.sh_rest[i * stride + column]);
      hi = std::max<double>(hi, in.sh_rest[i * stride + column]);
      levels.insert(out.sh_rest[i * stride + column]);
    }
    const double step = (hi - lo) / 255.0;
    EXPECT_LE(levels.size(), 256u);
    EXPECT_EQ(*levels.begin(), float(lo));
    EXPECT_EQ(*levels.rbegin(), float(hi));
    for (size_t i = 0; i < in.size(); ++i) {
      const double error = std::abs(double(out.sh_rest[i * stride + column]) -
                                    in.sh_rest[i * stride + column]);
      // Half a step, plus the float32 rounding of the reconstructed value.
      EXPECT_LE(error, step / 2 + 1e-7 * std::abs(hi - lo) + 1e-7);
    }
  }
  // Fewer bits, fewer levels.
  const GaussianModel coarse = Attacked("quant:2", in, &source);
  std::set<float> levels(coarse.opacity_logits.begin(),
                         coarse.opacity_logits.end());
  EXPECT_LE(levels.size(), 4u);
  EXPECT_GE(levels.size(), 2u);
}

TEST(FileAttacks, ShuffleIsAPermutationAndRendersIdentically) {
  const GaussianModel in = RandomScene(400, 2, 4);
  std::vector<uint32_t> source;
  const GaussianModel out = Attacked("shuffle", in, &source);
  ASSERT_EQ(source.size(), in.size());
  EXPECT_EQ(std::set<uint32_t>(source.begin(), source.end()).size(), in.size());
  size_t moved = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    moved += source[i] != i;
    EXPECT_EQ(out.opacity_logits[i], in.opacity_logits[source[i]]);
    EXPECT_EQ(out.quats[i * 4 + 2], in.quats[source[i] * 4 + 2]);
    EXPECT_EQ(out.sh_rest[i * 24 + 23], in.sh_rest[source[i] * 24 + 23]);
  }
  EXPECT_GT(moved, in.size() * 9 / 10);
  // Depths are distinct, so the depth sort restores the same blending order
  // and every pixel is computed by the same operations: bit-identical.
  const RenderCamera camera = TestCamera();
  EXPECT_EQ(Render(out, camera).data, Render(in, camera).data);
}

TEST(FileAttacks, ShBandRotationKeepsColourAlongRotatedDirections) {
  GaussianModel model = RandomScene(5, 3, 5);
  const GaussianModel original = model;
  SimilarityTransform transform = ParseSimilarity("73,0,0,0,1,0.3,-1,0.6");
  ApplySimilarity(transform, &model);
  std::mt19937_64 rng(6);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d d(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d rotated = transform.rotation * d;
    for (size_t i = 0; i < model.size(); ++i) {
      double before[3], after[3];
      ShColorUnclamped(3, &original.sh_dc[i * 3], &original.sh_rest[i * 45],
                       d.data(), before);
      ShColorUnclamped(3, &model.sh_dc[i * 3], &model.sh_rest[i * 45],
                       rotated.data(), after);
      // Coefficients are stored as float: relative rounding 6e-8 per term.
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(after[ch], before[ch], 1e-5);
    }
  }
}

TEST(FileAttacks, SimilarityWithMovedCamerasRendersTheSameImage) {
  const GaussianModel in = RandomScene(400, 3, 7);
  std::vector<uint32_t> source;
  const std::string text = "similarity:40,0.5,-2,1.25,2.5,1,2,3";
  const GaussianModel out = Attacked(text, in, &source);
  const SimilarityTransform transform = ParseModelAttack(text).similarity;
  const RenderCamera camera = TestCamera();
  const RenderCamera moved = TransformCamera(camera, transform);
  const ImageRGB before = Render(in, camera);
  const ImageRGB after = Render(out, moved);
  // float32 positions and coefficients: differences far below one 8-bit
  // level (1/255 = 3.9e-3).
  EXPECT_LT(MaxAbsDifference(before, after), 1e-4f);
  // Without rotating the SH the colours would change.
  GaussianModel unrotated_sh = out;
  unrotated_sh.sh_rest = in.sh_rest;
  EXPECT_GT(MaxAbsDifference(before, Render(unrotated_sh, moved)), 0.01f);
  // The unmoved camera sees a different image.
  EXPECT_GT(MaxAbsDifference(before, Render(out, camera)), 0.1f);
}

TEST(FileAttacks, SimilarityComposesAndRoundTripsThroughText) {
  const SimilarityTransform a = ParseSimilarity("30,1,2,3,2");
  const SimilarityTransform b = ParseSimilarity("-50,0.5,0,-1,0.25,1,1,0");
  const Eigen::Vector3d x(0.3, -0.7, 1.9);
  const auto apply = [](const SimilarityTransform& t,
                        const Eigen::Vector3d& p) {
    return Eigen::Vector3d(t.scale * t.rotation * p + t.translation);
  };
  EXPECT_LT((apply(b.After(a), x) - apply(b, apply(a, x))).norm(), 1e-12);
  const SimilarityTransform back = ParseSimilarity(ToString(b));
  // Ten significant digits.
  EXPECT_LT((back.rotation - b.rotation).norm(), 1e-9);
  EXPECT_LT((back.translation - b.translation).norm(), 1e-9);
  EXPECT_NEAR(back.scale, b.scale, 1e-10);
  EXPECT_EQ(ToString(a), "30,1,2,3,2,0,0,1");
  // 5 numbers: rotation about z.
  const Eigen::Vector3d z_axis = a.rotation * Eigen::Vector3d::UnitZ();
  EXPECT_LT((z_axis - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(FileAttacks, PruneRemovesExactlyTheGaussiansUnderTheThreshold) {
  const GaussianModel in = RandomScene(1000, 0, 8);
  std::vector<uint32_t> source;
  const GaussianModel out = Attacked("prune:0.3", in, &source);
  size_t next = 0;
  for (size_t i = 0; i < in.size(); ++i) {
    const double opacity =
        1.0 / (1.0 + std::exp(-double(in.opacity_logits[i])));
    if (opacity < 0.3) continue;
    ASSERT_LT(next, source.size());
    EXPECT_EQ(source[next], i);
    EXPECT_EQ(out.means[next * 3 + 1], in.means[i * 3 + 1]);
    ++next;
  }
  EXPECT_EQ(next, out.size());
  EXPECT_GT(out.size(), 0u);
  EXPECT_LT(out.size(), in.size());
}

TEST(FileAttacks, ParsesListsAndRefusesBadSpecs) {
  const auto specs = ParseModelAttackList(
      "similarity:30,1,0,-0.5,2,sh0,quant,gn:0.01,prune:.1");
  ASSERT_EQ(specs.size(), 5u);
  EXPECT_EQ(specs[0].kind, ModelAttackKind::kSimilarity);
  EXPECT_DOUBLE_EQ(specs[0].similarity.translation.z(), -0.5);
  EXPECT_EQ(specs[1].kind, ModelAttackKind::kShTruncation);
  EXPECT_EQ(specs[2].bits, 8);
  EXPECT_EQ(specs[3].distortion.kind, DistortionKind::kGaussianNoise);
  EXPECT_DOUBLE_EQ(specs[4].opacity_threshold, 0.1);
  // Text round trips (the similarity's, numerically: see above).
  for (size_t k = 1; k < specs.size(); ++k) {
    EXPECT_EQ(ToString(ParseModelAttack(ToString(specs[k]))),
              ToString(specs[k]));
  }
  for (const char* bad :
       {"quant:0", "quant:3.5", "prune:2", "prune:x", "similarity:1,2",
        "similarity:1,0,0,0,0", "similarity:1,0,0,0,1,0,0,0", "sh0:1", "blur:2",
        "dropout:1.5"}) {
    EXPECT_THROW(ParseModelAttackList(bad), Error) << bad;
  }
}

// spz, compressed_ply and splat run the formats' real encoders and decoders:
// the model keeps its count and SH degree (splat's dropped SH as zeros),
// moves by no more than the formats' steps, and renders nearly the same.
TEST(FileAttacks, CodecAttacksRoundTripThroughTheFormats) {
  const GaussianModel in = RandomScene(600, 3, 9);
  const RenderCamera camera = TestCamera();
  const ImageRGB before = Render(in, camera);
  for (const char* attack : {"spz", "spz:2", "compressed_ply", "splat"}) {
    const ModelAttackSpec spec = ParseModelAttack(attack);
    EXPECT_EQ(spec.kind, ModelAttackKind::kCodec) << attack;
    std::vector<uint32_t> source;
    const GaussianModel out = Attacked(attack, in, &source);
    ASSERT_EQ(out.size(), in.size()) << attack;
    ASSERT_EQ(out.sh_degree, 3) << attack;
    ASSERT_EQ(source.size(), in.size()) << attack;
    EXPECT_EQ(out.CountNonFinite(), 0u) << attack;
    std::vector<uint32_t> sorted = source;
    std::sort(sorted.begin(), sorted.end());
    for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i);
    double worst = 0;
    bool moved = false;
    for (size_t j = 0; j < out.size(); ++j) {
      for (int k = 0; k < 3; ++k) {
        const float a = in.means[3 * source[j] + k], b = out.means[3 * j + k];
        worst = std::max(worst, double(std::abs(a - b)));
        moved = moved || std::abs(in.log_scales[3 * source[j] + k] -
                                  out.log_scales[3 * j + k]) > 1e-6;
      }
    }
    // Positions: SPZ 2^-13, compressed PLY a chunk's range / 2046, .splat
    // float32 (exact).
    EXPECT_LE(worst, 2e-3) << attack;
    if (std::string(attack) == "splat") {
      EXPECT_EQ(*std::max_element(out.sh_rest.begin(), out.sh_rest.end()), 0.f);
      EXPECT_EQ(*std::min_element(out.sh_rest.begin(), out.sh_rest.end()), 0.f);
    } else {
      EXPECT_TRUE(moved) << attack;
      EXPECT_LT(MaxAbsDifference(before, Render(out, camera)), 0.25) << attack;
    }
  }
  EXPECT_EQ(ToString(ParseModelAttack("spz")), "spz:3");
  EXPECT_EQ(ToString(ParseModelAttack("spz:2")), "spz:2");
  EXPECT_EQ(ToString(ParseModelAttack("compressed_ply")), "compressed_ply");
  EXPECT_EQ(ToString(ParseModelAttack("splat")), "splat");
  EXPECT_EQ(ParseModelAttackList("spz:2,splat").size(), 2u);
  for (const char* bad : {"spz:4", "spz:x", "splat:1", "compressed_ply:8"}) {
    EXPECT_THROW(ParseModelAttack(bad), Error) << bad;
  }
}

}  // namespace
}  // namespace watergs
