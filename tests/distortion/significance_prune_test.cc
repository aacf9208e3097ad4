// Tests of LightGaussian-style significance pruning: the score is the blend
// weight the cameras see (times the volume factor), the pruned model keeps
// exactly the highest-scored Gaussians, and bad inputs are refused.
#include "distortion/significance_prune.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "distortion/file_attacks.h"
#include "gaussian/util/error.h"
#include "tests/common/look_at.h"
#include "tests/common/random_model.h"

namespace watergs {
namespace {

GaussianModel Scene(size_t n, uint64_t seed) { return RandomModel(n, 1, seed); }

std::vector<RenderCamera> Cameras() {
  return {LookAtOrigin(Eigen::Vector3d(3.0, -2.0, 1.5), 64, 48),
          LookAtOrigin(Eigen::Vector3d(-2.5, 2.5, 1.0), 64, 48),
          LookAtOrigin(Eigen::Vector3d(0.5, 3.5, -1.0), 64, 48)};
}

TEST(SignificancePrune, ScoreIsTheSummedBlendWeightWithoutVolumeFactor) {
  const GaussianModel model = Scene(200, 1);
  const auto cameras = Cameras();
  auto rasterizer = MakeCpuRasterizer();
  std::vector<double> expected(model.size(), 0.0);
  for (const RenderCamera& c : cameras) {
    rasterizer->AccumulateBlendWeights(model, c, RenderOptions(), &expected);
  }
  const std::vector<double> scores =
      SignificanceScores(model, cameras, *rasterizer, 0.0);
  ASSERT_EQ(scores.size(), model.size());
  for (size_t i = 0; i < model.size(); ++i) EXPECT_EQ(scores[i], expected[i]);
  // With LightGaussian's volume factor: score / weight = exp(0.1 (log V -
  // log V_p90)), so log(score / weight) - 0.1 log V is one constant.
  const std::vector<double> with_volume =
      SignificanceScores(model, cameras, *rasterizer);
  const auto offset = [&](size_t i) {
    double log_volume = 0;
    for (int k = 0; k < 3; ++k) log_volume += model.log_scales[3 * i + k];
    return std::log(with_volume[i] / expected[i]) -
           kSignificanceVolumePower * log_volume;
  };
  int seen = 0;
  double first = 0;
  for (size_t i = 0; i < model.size(); ++i) {
    EXPECT_GE(with_volume[i], 0.0);
    if (expected[i] == 0) {
      EXPECT_EQ(with_volume[i], 0.0);
      continue;
    }
    if (seen++ == 0) first = offset(i);
    EXPECT_NEAR(offset(i), first, 1e-6) << i;
  }
  EXPECT_GT(seen, 100);  // most Gaussians are seen
}

TEST(SignificancePrune, KeepsTheMostSignificantAndTheOrder) {
  const GaussianModel model = Scene(300, 2);
  const auto cameras = Cameras();
  auto rasterizer = MakeCpuRasterizer();
  const std::vector<double> scores =
      SignificanceScores(model, cameras, *rasterizer);
  std::mt19937_64 rng(0);
  GaussianModel out;
  std::vector<uint32_t> source;
  ApplyModelAttack(ParseModelAttack("prune_significance:0.4"), model, rng, &out,
                   &source, &cameras);
  ASSERT_EQ(out.size(), 300u - 120u);
  ASSERT_EQ(source.size(), out.size());
  std::vector<bool> kept(model.size(), false);
  for (size_t k = 0; k < source.size(); ++k) {
    if (k > 0) {
      EXPECT_LT(source[k - 1], source[k]);  // order kept
    }
    kept[source[k]] = true;
    EXPECT_EQ(out.means[3 * k], model.means[3 * source[k]]);
  }
  double lowest_kept = INFINITY, highest_removed = -INFINITY;
  for (size_t i = 0; i < model.size(); ++i) {
    if (kept[i]) {
      lowest_kept = std::min(lowest_kept, scores[i]);
    } else {
      highest_removed = std::max(highest_removed, scores[i]);
    }
  }
  EXPECT_LE(highest_removed, lowest_kept);
  // Pruning by significance costs the renders less than removing the same
  // number of Gaussians with the highest scores.
  std::vector<double> negated(scores.size());
  for (size_t i = 0; i < scores.size(); ++i) negated[i] = -scores[i];
  GaussianModel worst;
  std::vector<uint32_t> worst_source;
  PruneLowestScores(0.4, negated, model, &worst, &worst_source);
  const auto error = [&](const GaussianModel& m) {
    double sum = 0;
    for (const RenderCamera& c : cameras) {
      ImageRGB a, b;
      rasterizer->Forward(model, c, RenderOptions(), &a, nullptr);
      rasterizer->Forward(m, c, RenderOptions(), &b, nullptr);
      for (size_t k = 0; k < a.data.size(); ++k) {
        sum += std::abs(a.data[k] - b.data[k]);
      }
    }
    return sum;
  };
  EXPECT_LT(error(out), 0.5 * error(worst));
}

TEST(SignificancePrune, HardCasesStayFinite) {
  GaussianModel model = Scene(50, 3);
  model.opacity_logits[0] = -INFINITY;  // zero opacity
  model.opacity_logits[1] = -20.f;
  model.log_scales[3 * 2] = -INFINITY;  // flat
  model.log_scales[3 * 3] = 80.f;       // huge
  model.log_scales[3 * 3 + 1] = 80.f;
  model.means[3 * 4] = 1e30f;  // far away
  const auto cameras = Cameras();
  auto rasterizer = MakeCpuRasterizer();
  const std::vector<double> scores =
      SignificanceScores(model, cameras, *rasterizer);
  for (double s : scores) {
    EXPECT_TRUE(std::isfinite(s));
    EXPECT_GE(s, 0.0);
  }
  EXPECT_EQ(scores[0], 0.0);
  GaussianModel out;
  std::vector<uint32_t> source;
  PruneLowestScores(0.1, scores, model, &out, &source);
  EXPECT_EQ(out.size(), 45u);
  EXPECT_EQ(std::count(source.begin(), source.end(), 0u), 0);  // pruned first
  GaussianModel empty, pruned_empty;
  PruneLowestScores(0.5, {}, empty, &pruned_empty, &source);
  EXPECT_EQ(pruned_empty.size(), 0u);
}

TEST(SignificancePrune, RefusesBadFractionsAndMissingCameras) {
  for (const char* bad :
       {"prune_significance", "prune_significance:", "prune_significance:1",
        "prune_significance:-0.1", "prune_significance:nan",
        "prune_significance:0.5x"}) {
    EXPECT_THROW(ParseModelAttack(bad), Error) << bad;
  }
  EXPECT_EQ(ToString(ParseModelAttack("prune_significance:0.25")),
            "prune_significance:0.25");
  const GaussianModel model = Scene(10, 4);
  std::mt19937_64 rng(0);
  GaussianModel out;
  std::vector<uint32_t> source;
  const ModelAttackSpec spec = ParseModelAttack("prune_significance:0.5");
  EXPECT_TRUE(AttackNeedsCameras(spec));
  EXPECT_FALSE(AttackNeedsCameras(ParseModelAttack("decimate:0.5")));
  try {
    ApplyModelAttack(spec, model, rng, &out, &source);
    ADD_FAILURE() << "no cameras accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--workspace_path"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(PruneLowestScores(1.0, std::vector<double>(10, 0.0), model, &out,
                                 &source),
               Error);
}

}  // namespace
}  // namespace watergs
