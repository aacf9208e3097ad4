#include "distortion/distortion_layer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// A model whose every value encodes its Gaussian's index, so survivors can be
// traced: means[i] = (i, i + 0.25, i + 0.5), opacity[i] = -i, ...
GaussianModel IndexedModel(size_t n, int sh_degree = 1) {
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      m.means[i * 3 + k] = float(i) + 0.25f * k;
      m.log_scales[i * 3 + k] = -float(i);
      m.sh_dc[i * 3 + k] = float(i) * 2;
    }
    for (int k = 0; k < 4; ++k) m.quats[i * 4 + k] = float(i) + k;
    m.opacity_logits[i] = -float(i);
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[i * m.sh_rest_stride() + k] = float(i) * 3;
    }
  }
  return m;
}

void ExpectRowsFromSource(const GaussianModel& in, const GaussianModel& out,
                          const std::vector<uint32_t>& source) {
  ASSERT_EQ(out.size(), source.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const size_t s = source[i];
    EXPECT_EQ(out.opacity_logits[i], in.opacity_logits[s]);
    EXPECT_EQ(out.quats[i * 4 + 3], in.quats[s * 4 + 3]);
    EXPECT_EQ(out.sh_rest[i * out.sh_rest_stride()],
              in.sh_rest[s * in.sh_rest_stride()]);
  }
}

TEST(DistortionLayer, DropoutRemovesExactFractionKeepingOrder) {
  const GaussianModel in = IndexedModel(1000);
  auto layer = MakeDistortionLayer({DistortionKind::kDropout, 0.1, 1});
  std::mt19937_64 rng(3);
  GaussianModel out;
  std::vector<uint32_t> source;
  layer->Apply(in, rng, &out, &source);
  EXPECT_EQ(out.size(), 900u);
  EXPECT_TRUE(std::is_sorted(source.begin(), source.end()));
  EXPECT_EQ(std::adjacent_find(source.begin(), source.end()), source.end());
  ExpectRowsFromSource(in, out, source);
  // Removed Gaussians are spread over the file, not one block.
  EXPECT_GT(source.back() - source.front(), 990u);
  std::vector<uint32_t> again;
  layer->Apply(in, rng, &out, &again);
  EXPECT_NE(source, again);
}

TEST(DistortionLayer, CropRemovesOneContiguousRun) {
  const GaussianModel in = IndexedModel(1000);
  auto layer = MakeDistortionLayer({DistortionKind::kCrop, 0.25, 1});
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    GaussianModel out;
    std::vector<uint32_t> source;
    layer->Apply(in, rng, &out, &source);
    ASSERT_EQ(out.size(), 750u);
    ExpectRowsFromSource(in, out, source);
    int gaps = 0;
    size_t gap_size = 0;
    if (source.front() != 0) gaps++, gap_size += source.front();
    for (size_t i = 1; i < source.size(); ++i) {
      if (source[i] != source[i - 1] + 1) {
        ++gaps;
        gap_size += source[i] - source[i - 1] - 1;
      }
    }
    if (source.back() != 999) gaps++, gap_size += 999 - source.back();
    EXPECT_EQ(gaps, 1);
    EXPECT_EQ(gap_size, 250u);
  }
}

TEST(DistortionLayer, GaussianNoiseMovesOnlyMeansWithRequestedSigma) {
  const GaussianModel in = IndexedModel(20000, 0);
  auto layer = MakeDistortionLayer({DistortionKind::kGaussianNoise, 0.01, 1});
  std::mt19937_64 rng(7);
  GaussianModel out;
  std::vector<uint32_t> source;
  layer->Apply(in, rng, &out, &source);
  ASSERT_EQ(out.size(), in.size());
  double sum = 0, sum_sq = 0;
  for (size_t i = 0; i < in.means.size(); ++i) {
    const double d = double(out.means[i]) - double(in.means[i]);
    sum += d;
    sum_sq += d * d;
  }
  const double n = double(in.means.size());
  const double mean = sum / n;
  const double sigma = std::sqrt(sum_sq / n - mean * mean);
  // 60k samples: the standard error of sigma is ~0.3%, of the mean ~4e-5.
  EXPECT_NEAR(sigma, 0.01, 0.01 * 0.03);
  EXPECT_NEAR(mean, 0.0, 2e-4);
  EXPECT_EQ(out.opacity_logits, in.opacity_logits);
  EXPECT_EQ(out.quats, in.quats);
  EXPECT_EQ(out.log_scales, in.log_scales);
}

TEST(DistortionLayer, ScatterSendsGradientsToSurvivorsOnly) {
  const GaussianModel in = IndexedModel(50);
  auto layer = MakeDistortionLayer({DistortionKind::kCrop, 0.2, 1});
  std::mt19937_64 rng(1);
  GaussianModel out;
  std::vector<uint32_t> source;
  layer->Apply(in, rng, &out, &source);
  GaussianGradients distorted;
  distorted.Reset(out.size(), out.sh_rest_stride());
  for (size_t i = 0; i < out.size(); ++i) {
    distorted.opacity_logits[i] = 1.0f + i;
    distorted.means[i * 3 + 1] = 2.0f + i;
    distorted.mean2d_grad_norm_ndc[i] = 4.0f + i;
    distorted.sh_rest[i * out.sh_rest_stride() + 2] = 3.0f + i;
    distorted.visible[i] = 1;
  }
  GaussianGradients grads;
  ScatterGradients(distorted, source, in.size(), in.sh_rest_stride(), &grads);
  std::vector<int> survivor_of(in.size(), -1);
  for (size_t i = 0; i < source.size(); ++i) survivor_of[source[i]] = int(i);
  for (size_t j = 0; j < in.size(); ++j) {
    const int i = survivor_of[j];
    EXPECT_EQ(grads.opacity_logits[j], i < 0 ? 0.f : 1.0f + i);
    EXPECT_EQ(grads.means[j * 3 + 1], i < 0 ? 0.f : 2.0f + i);
    EXPECT_EQ(grads.sh_rest[j * in.sh_rest_stride() + 2],
              i < 0 ? 0.f : 3.0f + i);
    EXPECT_EQ(grads.mean2d_grad_norm_ndc[j], i < 0 ? 0.f : 4.0f + i);
    EXPECT_EQ(grads.visible[j], i < 0 ? 0 : 1);
  }
}

TEST(DistortionLayer, EmptyModelAndZeroFractionAreFine) {
  GaussianModel empty;
  empty.Resize(0);
  std::mt19937_64 rng(1);
  for (auto kind : {DistortionKind::kGaussianNoise, DistortionKind::kDropout,
                    DistortionKind::kCrop}) {
    GaussianModel out;
    std::vector<uint32_t> source;
    MakeDistortionLayer({kind, 0.1, 1})->Apply(empty, rng, &out, &source);
    EXPECT_EQ(out.size(), 0u);
    MakeDistortionLayer({kind, 0.0, 1})
        ->Apply(IndexedModel(10), rng, &out, &source);
    EXPECT_EQ(out.size(), 10u);
  }
}

TEST(DistortionSpecParsing, AcceptsDocumentedFormsAndRejectsOthers) {
  EXPECT_EQ(ParseDistortionSpec("identity").kind, DistortionKind::kIdentity);
  const auto gn = ParseDistortionSpec("gn:0.02@3");
  EXPECT_EQ(gn.kind, DistortionKind::kGaussianNoise);
  EXPECT_DOUBLE_EQ(gn.strength, 0.02);
  EXPECT_DOUBLE_EQ(gn.weight, 3);
  EXPECT_EQ(ParseDistortionList("identity,dropout:0.1,crop:0.1").size(), 3u);
  for (const char* bad :
       {"", "gn", "gn:", "gn:abc", "gn:-1", "dropout:1", "crop:1.5", "blur:1",
        "gn:0.1@0", "gn:0.1@x", "gn:nan", "identity:3"}) {
    EXPECT_THROW(ParseDistortionList(bad), Error) << bad;
  }
  EXPECT_EQ(ToString(ParseDistortionSpec("crop:0.1")), "crop:0.1");
}

TEST(DistortionSampler, SamplesInProportionToWeights) {
  DistortionSampler sampler(ParseDistortionList("identity@1,gn:0.01@3"));
  EXPECT_FALSE(sampler.IdentityOnly());
  std::mt19937_64 rng(11);
  int identity = 0;
  const int trials = 40000;
  for (int i = 0; i < trials; ++i) identity += sampler.Sample(rng).IsIdentity();
  // Expected 10000, binomial sd ~87.
  EXPECT_NEAR(identity, trials / 4, 400);
  EXPECT_TRUE(
      DistortionSampler(ParseDistortionList("identity")).IdentityOnly());
}

}  // namespace
}  // namespace watergs
