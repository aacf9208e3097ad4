// Parity tests of the CUDA 3D distortion layers
// (distortion/cuda/cuda_distortion.h) against the CPU layers
// (distortion_layer.h). Crop and Identity draw from the rng as the CPU does
// and must give the CPU's output exactly. Noise and dropout use a device
// random stream, so their tests check the deterministic parts exactly (row
// copies, counts, order, reproducibility for one seed) and the random parts
// statistically with stated bounds. They run when a GPU is visible.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include "distortion/distortion_layer.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"

#ifdef WATERGS_WITH_CUDA
#include "distortion/cuda/cuda_distortion.h"
#endif

namespace watergs {
namespace {

#ifdef WATERGS_WITH_CUDA

// Every value encodes its Gaussian's index and array, so survivors can be
// traced and any mixed-up row or array shows.
GaussianModel IndexedModel(size_t n, int sh_degree = 2) {
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      m.means[i * 3 + k] = float(i) + 0.25f * k;
      m.log_scales[i * 3 + k] = -float(i) - 0.125f * k;
      m.sh_dc[i * 3 + k] = float(i) * 2 + k;
    }
    for (int k = 0; k < 4; ++k) m.quats[i * 4 + k] = float(i) + 0.5f * k;
    m.opacity_logits[i] = -float(i);
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[i * m.sh_rest_stride() + k] = float(i) * 3 + 0.01f * k;
    }
  }
  return m;
}

// Every array of `out` is `in` gathered by `source`; means compared only if
// compare_means (noise moves them).
void ExpectGathered(const GaussianModel& in, const GaussianModel& out,
                    const std::vector<uint32_t>& source, bool compare_means) {
  ASSERT_EQ(out.size(), source.size());
  ASSERT_EQ(out.sh_degree, in.sh_degree);
  auto rows = [&](const std::vector<float>& a, const std::vector<float>& b,
                  size_t stride) {
    ASSERT_EQ(b.size(), source.size() * stride);
    for (size_t i = 0; i < source.size(); ++i) {
      for (size_t k = 0; k < stride; ++k) {
        ASSERT_EQ(b[i * stride + k], a[source[i] * stride + k]);
      }
    }
  };
  if (compare_means) rows(in.means, out.means, 3);
  rows(in.log_scales, out.log_scales, 3);
  rows(in.quats, out.quats, 4);
  rows(in.opacity_logits, out.opacity_logits, 1);
  rows(in.sh_dc, out.sh_dc, 3);
  rows(in.sh_rest, out.sh_rest, in.sh_rest_stride());
}

DistortionSpec Spec(DistortionKind kind, double strength) {
  DistortionSpec spec;
  spec.kind = kind;
  spec.strength = strength;
  return spec;
}

TEST(CudaDistortion, CropAndIdentityEqualTheCpuLayers) {
  WATERGS_REQUIRE_CUDA();
  const GaussianModel in = IndexedModel(1001);
  for (const DistortionSpec& spec :
       {Spec(DistortionKind::kIdentity, 0), Spec(DistortionKind::kCrop, 0),
        Spec(DistortionKind::kCrop, 0.1), Spec(DistortionKind::kCrop, 0.37),
        Spec(DistortionKind::kCrop, 0.999)}) {
    for (uint64_t seed : {1u, 2u, 3u}) {
      std::mt19937_64 rng_cpu(seed), rng_cuda(seed);
      GaussianModel out_cpu, out_cuda;
      std::vector<uint32_t> source_cpu, source_cuda;
      MakeDistortionLayer(spec)->Apply(in, rng_cpu, &out_cpu, &source_cpu);
      CudaDistortionLayer(spec).Apply(in, rng_cuda, &out_cuda, &source_cuda);
      EXPECT_EQ(source_cpu, source_cuda) << ToString(spec);
      EXPECT_EQ(out_cpu.means, out_cuda.means) << ToString(spec);
      EXPECT_EQ(out_cpu.log_scales, out_cuda.log_scales);
      EXPECT_EQ(out_cpu.quats, out_cuda.quats);
      EXPECT_EQ(out_cpu.opacity_logits, out_cuda.opacity_logits);
      EXPECT_EQ(out_cpu.sh_dc, out_cuda.sh_dc);
      EXPECT_EQ(out_cpu.sh_rest, out_cuda.sh_rest);
      // Both consumed the same draws.
      EXPECT_EQ(rng_cpu(), rng_cuda()) << ToString(spec);
    }
  }
}

TEST(CudaDistortion, DropoutRemovesExactCountUniformly) {
  WATERGS_REQUIRE_CUDA();
  const size_t n = 200;
  const double p = 0.3;
  const int trials = 400;
  const GaussianModel in = IndexedModel(n);
  CudaDistortionLayer layer(Spec(DistortionKind::kDropout, p));
  std::mt19937_64 rng(5);
  std::vector<int> removed_count(n, 0);
  std::vector<uint32_t> first_source;
  for (int t = 0; t < trials; ++t) {
    GaussianModel out;
    std::vector<uint32_t> source;
    layer.Apply(in, rng, &out, &source);
    // Exactly round(p n) removed, survivors in file order, rows intact.
    ASSERT_EQ(source.size(), n - 60);
    for (size_t i = 1; i < source.size(); ++i) {
      ASSERT_LT(source[i - 1], source[i]);
    }
    ASSERT_LT(source.back(), n);
    ExpectGathered(in, out, source, true);
    std::vector<bool> kept(n, false);
    for (uint32_t s : source) kept[s] = true;
    for (size_t i = 0; i < n; ++i) removed_count[i] += kept[i] ? 0 : 1;
    if (t == 0) first_source = source;
    if (t == 1) {
      EXPECT_NE(source, first_source);  // a fresh subset each time
    }
  }
  // Each Gaussian is removed Binomial(400, 0.3) times: mean 120, sd 9.17.
  // 5.5 sd either side: a false alarm over 200 Gaussians has probability
  // ~1e-5, while an index-dependent rule (e.g. always the first 60) fails.
  const double mean = trials * p, sd = std::sqrt(trials * p * (1 - p));
  for (size_t i = 0; i < n; ++i) {
    EXPECT_NEAR(removed_count[i], mean, 5.5 * sd) << "Gaussian " << i;
  }
  // The same rng state gives the same subset.
  std::mt19937_64 a(77), b(77);
  GaussianModel out_a, out_b;
  std::vector<uint32_t> source_a, source_b;
  layer.Apply(in, a, &out_a, &source_a);
  layer.Apply(in, b, &out_b, &source_b);
  EXPECT_EQ(source_a, source_b);
}

TEST(CudaDistortion, GaussianNoiseMovesOnlyMeansWithRequestedSigma) {
  WATERGS_REQUIRE_CUDA();
  const size_t n = 100000;
  const double sigma = 0.01;
  GaussianModel in = IndexedModel(n, 1);
  std::fill(in.means.begin(), in.means.end(), 0.f);  // out.means = the noise
  CudaDistortionLayer layer(Spec(DistortionKind::kGaussianNoise, sigma));
  std::mt19937_64 rng(6);
  GaussianModel out;
  std::vector<uint32_t> source;
  layer.Apply(in, rng, &out, &source);
  ASSERT_EQ(source.size(), n);
  for (size_t i = 0; i < n; ++i) ASSERT_EQ(source[i], i);
  ExpectGathered(in, out, source, false);
  const size_t count = out.means.size();
  double sum = 0, sum_sq = 0, lag = 0;
  size_t beyond_2sigma = 0;
  for (size_t j = 0; j < count; ++j) {
    const double z = out.means[j];
    ASSERT_TRUE(std::isfinite(z));
    sum += z;
    sum_sq += z * z;
    if (j > 0) lag += z * out.means[j - 1];
    beyond_2sigma += std::abs(z) > 2 * sigma ? 1 : 0;
  }
  // 5 standard errors each, for count = 3e5 normal samples:
  // mean: sigma / sqrt(count); std: sigma / sqrt(2 count); fraction beyond
  // 2 sigma (0.0455): binomial; lag-1 correlation: 1 / sqrt(count).
  const double mean = sum / count;
  const double sd = std::sqrt(sum_sq / count - mean * mean);
  EXPECT_NEAR(mean, 0.0, 5 * sigma / std::sqrt(double(count)));
  EXPECT_NEAR(sd, sigma, 5 * sigma / std::sqrt(2.0 * count));
  const double tail = double(beyond_2sigma) / count;
  EXPECT_NEAR(tail, 0.0455, 5 * std::sqrt(0.0455 * 0.9545 / count));
  EXPECT_NEAR(lag / count / (sigma * sigma), 0.0, 5 / std::sqrt(double(count)));
  // Reproducible for one rng state; sigma 0 leaves the means unchanged.
  std::mt19937_64 again(6);
  GaussianModel out_again;
  layer.Apply(in, again, &out_again, &source);
  EXPECT_EQ(out.means, out_again.means);
  GaussianModel indexed = IndexedModel(50), still;
  CudaDistortionLayer(Spec(DistortionKind::kGaussianNoise, 0))
      .Apply(indexed, rng, &still, &source);
  EXPECT_EQ(still.means, indexed.means);
}

TEST(CudaDistortion, ScatterSendsGradientsToSourcesLikeCpu) {
  WATERGS_REQUIRE_CUDA();
  const GaussianModel in = IndexedModel(300);
  std::mt19937_64 rng(8);
  DeviceGaussianArrays device_in, device_out;
  device_in.Upload(in);
  DeviceBuffer<uint32_t> source;
  CudaDistortionLayer(Spec(DistortionKind::kDropout, 0.25))
      .Apply(device_in, rng, &device_out, &source);
  std::vector<uint32_t> host_source;
  source.Download(&host_source);
  // Distorted-model gradients: distinct values per row.
  GaussianGradients distorted;
  distorted.Reset(host_source.size(), in.sh_rest_stride());
  for (size_t j = 0; j < distorted.means.size(); ++j) {
    distorted.means[j] = 0.5f + float(j);
  }
  for (size_t j = 0; j < distorted.sh_rest.size(); ++j) {
    distorted.sh_rest[j] = -float(j);
  }
  GaussianGradients cpu;
  ScatterGradients(distorted, host_source, in.size(), in.sh_rest_stride(),
                   &cpu);
  for (auto [from, expected, stride] :
       {std::tuple{&distorted.means, &cpu.means, 3},
        std::tuple{&distorted.sh_rest, &cpu.sh_rest, in.sh_rest_stride()}}) {
    DeviceBuffer<float> d_from, d_to;
    d_from.Upload(*from);
    d_to.Resize(expected->size());
    d_to.Zero();
    CudaScatterRows(d_from.data(), source, host_source.size(), stride,
                    d_to.data());
    std::vector<float> got;
    d_to.Download(&got);
    EXPECT_EQ(got, *expected);
  }
}

TEST(CudaDistortion, RejectsStrengthsOutOfRange) {
  // Validation needs no device.
  EXPECT_THROW(CudaDistortionLayer(Spec(DistortionKind::kDropout, 1.0)), Error);
  EXPECT_THROW(CudaDistortionLayer(Spec(DistortionKind::kGaussianNoise, -1)),
               Error);
}

#else

TEST(CudaDistortion, SkippedWithoutCudaBackend) { WATERGS_REQUIRE_CUDA(); }

#endif

}  // namespace
}  // namespace watergs
