// Parity tests of the CUDA density control (gaussian/cuda/cuda_density.h)
// against the CPU Inria strategy (gaussian/density_strategy.h, itself tested
// in density_test.cc): from the same model, Adam moments, gradients and
// radii over several iterations both clone, split and prune the same
// Gaussians, reset the same opacities, keep byte-identical statistics and
// RNG state (SaveState), and leave the same moments. The GPU tests run when
// a GPU is visible; without one, the fixture check (the CPU strategy does
// clone, split and prune on it) and the constructor's error still run.
//
// Tolerance: gathers, opacity resets and moment copies are exact copies of
// the same float operations, so they must match bit for bit. Split-sample
// means add an offset computed in double (exp and the rotation) and rounded
// to float; the device evaluates the same operations unfused, so the offset
// may differ from the host's by one double rounding, which after the float
// rounding of mean + offset differs by at most eps |offset| <= 2 eps M plus
// eps M (M: the largest of |parent mean| and |result|): allowed 4 eps M. A
// wrong sample, scale or rotation moves a mean by ~the Gaussian's scale (~1e-3
// or more here), far more.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/density_strategy.h"
#include "gaussian/device.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_adam.h"
#include "gaussian/cuda/cuda_density.h"
#include "gaussian/cuda/cuda_model_mirror.h"
#include "gaussian/cuda/device_buffer.h"
#endif

namespace watergs {
namespace {

constexpr ParamGroup kAllGroups[] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

// A schedule that densifies at 3, 6, 9, resets opacity at 7 and applies the
// size limits (screen radius 20 px, world size 0.1 x extent) from 8 on.
DensityOptions ShortSchedule() {
  DensityOptions options;
  options.densify_from_iter = 2;
  options.densify_until_iter = 100;
  options.densification_interval = 3;
  options.opacity_reset_interval = 7;
  options.seed = 17;
  return options;
}

// ShortSchedule with a white background (an extra reset at iteration 2),
// three samples per split and no screen-size pruning (no radii).
DensityOptions WhiteBackgroundOptions() {
  DensityOptions options = ShortSchedule();
  options.white_background = true;
  options.split_samples = 3;
  options.max_screen_size = 0;
  return options;
}

// Scales around percent_dense x extent (0.01), so that both clones and
// splits occur; some opacities and scales are past the pruning limits.
GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed) {
  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal;
  for (float& v : model.means) v = normal(rng);
  for (float& v : model.log_scales) v = std::log(0.01f) + 1.2f * normal(rng);
  for (float& v : model.quats) v = normal(rng);
  for (float& v : model.opacity_logits) v = -2.f + 2.5f * normal(rng);
  for (float& v : model.sh_dc) v = normal(rng);
  for (float& v : model.sh_rest) v = normal(rng);
  return model;
}

// One view's statistics for n Gaussians: ~80% visible, NDC norms with mean
// 2e-4 (about a third above the threshold on average), radii 0-30 px.
struct HostView {
  GaussianGradients grads;
  std::vector<float> radii;

  HostView(size_t n, uint32_t seed) {
    grads.Reset(n, 0);
    radii.resize(n);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uniform(0.f, 1.f);
    std::exponential_distribution<float> exponential(1.f / 2e-4f);
    for (size_t i = 0; i < n; ++i) {
      grads.visible[i] = uniform(rng) < 0.8f;
      grads.mean2d_grad_norm_ndc[i] = exponential(rng);
      radii[i] = grads.visible[i] ? 30.f * uniform(rng) : 0.f;
    }
  }
};

// Totals of a CPU run over iterations 1..last with RunParity's views.
struct CpuTotals {
  size_t cloned = 0, split = 0, pruned = 0, resets = 0;
};

CpuTotals RunCpu(GaussianModel model, const DensityOptions& options,
                 int64_t last, uint32_t seed) {
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  auto cpu = MakeInriaDensityStrategy(options, 1.0);
  cpu->Init(model);
  CpuTotals totals;
  for (int64_t it = 1; it <= last; ++it) {
    HostView view(model.size(), seed * 1000 + uint32_t(it));
    const size_t before = model.size();
    const DensityEvent event = cpu->PostBackward(
        it, view.grads, cpu->WantsRadii(it) ? &view.radii : nullptr, &model,
        &adam);
    totals.cloned += event.cloned, totals.split += event.split;
    totals.pruned += event.pruned, totals.resets += event.opacity_reset;
    EXPECT_EQ(model.size(), adam.size());
    if (event.densified) {  // each split Gaussian becomes split_samples
      EXPECT_EQ(model.size(), before + event.cloned +
                                  event.split * (options.split_samples - 1) -
                                  event.pruned);
    }
  }
  return totals;
}

// The parity runs below are only meaningful if the CPU strategy clones,
// splits, prunes and resets on their fixtures: checked here, with or
// without a GPU (same models, options and views as the GPU tests).
TEST(CudaDensityTest, FixturesExerciseCloneSplitPruneAndResetOnTheCpu) {
  for (int sh_degree : {0, 3}) {
    const CpuTotals totals = RunCpu(RandomModel(3000, sh_degree, 5 + sh_degree),
                                    ShortSchedule(), 10, 7 + sh_degree);
    EXPECT_GT(totals.cloned, 0u);
    EXPECT_GT(totals.split, 0u);
    EXPECT_GT(totals.pruned, 0u);
    EXPECT_EQ(totals.resets, 1u);
  }
  const CpuTotals white =
      RunCpu(RandomModel(2000, 1, 11), WhiteBackgroundOptions(), 10, 13);
  EXPECT_GT(white.cloned, 0u);
  EXPECT_GT(white.split, 0u);
  EXPECT_EQ(white.resets, 2u);  // at densify_from_iter and at 7
}

#ifdef WATERGS_WITH_CUDA

// Random moments in a CPU Adam sized to `model`.
void RandomMoments(const GaussianModel& model, uint32_t seed, Adam* adam) {
  adam->Init(model);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal;
  for (ParamGroup g : kAllGroups) {
    AdamGroupState& state = adam->state(g);
    for (float& v : state.exp_avg) v = normal(rng);
    for (float& v : state.exp_avg_sq) v = std::abs(normal(rng));
    state.step = 5;
  }
}

// The model's arrays on the device.
struct DeviceModel : DeviceGaussianArrays {
  explicit DeviceModel(const GaussianModel& model) { Upload(model); }
  CudaDensityModel Ref() { return DensityModel(); }
  GaussianModel Host() const {
    GaussianModel model;
    Download(&model);
    return model;
  }
};

// A HostView and its device copy.
struct ViewStats {
  GaussianGradients grads;
  std::vector<float> radii;
  DeviceBuffer<uint8_t> visible;
  DeviceBuffer<float> norm_ndc, device_radii;

  ViewStats(size_t n, uint32_t seed) {
    HostView host(n, seed);
    grads = std::move(host.grads);
    radii = std::move(host.radii);
    visible.Upload(grads.visible);
    norm_ndc.Upload(grads.mean2d_grad_norm_ndc);
    device_radii.Upload(radii);
  }
  CudaGradientArrays Arrays() {
    CudaGradientArrays arrays;
    arrays.visible = visible.data();
    arrays.mean2d_grad_norm_ndc = norm_ndc.data();
    return arrays;
  }
};

// Every value equal, but the means of split samples (rows with
// sample_scale[row] > 0) within 4 eps of sample_scale[row], the largest
// magnitude among the row's parent mean and result (see the file comment).
void ExpectModelsMatch(const GaussianModel& cpu, const GaussianModel& gpu,
                       const std::vector<float>& sample_scale,
                       const std::string& where) {
  ASSERT_EQ(cpu.size(), gpu.size()) << where;
  for (ParamGroup g : kAllGroups) {
    const std::vector<float>& a = GroupParams(cpu, g);
    const std::vector<float>& b = GroupParams(gpu, g);
    ASSERT_EQ(a.size(), b.size()) << where << " " << GroupName(g);
    for (size_t k = 0; k < a.size(); ++k) {
      if (g == ParamGroup::kXyz && sample_scale[k / 3] > 0) {
        const float tol = 4 * FLT_EPSILON * sample_scale[k / 3];
        ASSERT_NEAR(a[k], b[k], tol) << where << " mean value " << k;
      } else {
        ASSERT_EQ(a[k], b[k]) << where << " " << GroupName(g) << " " << k;
      }
    }
  }
}

// For each row of `after` (a CPU densification of `before` with `parent`)
// whose mean the CPU moved (a split sample): the largest magnitude of its
// parent's and its own mean values; 0 for the other rows.
std::vector<float> SampleScales(const GaussianModel& before,
                                const GaussianModel& after,
                                const std::vector<int64_t>& parent) {
  std::vector<float> scale(after.size(), 0.f);
  for (size_t j = 0; j < after.size(); ++j) {
    bool moved = false;
    float largest = 0.f;
    for (int a = 0; a < 3; ++a) {
      const float from = before.means[3 * parent[j] + a];
      const float to = after.means[3 * j + a];
      moved = moved || from != to;
      largest = std::max({largest, std::abs(from), std::abs(to)});
    }
    if (moved) scale[j] = largest;
  }
  return scale;
}

void ExpectMomentsMatch(Adam& cpu, const CudaAdam& gpu,
                        const std::string& where) {
  ASSERT_EQ(cpu.size(), gpu.size()) << where;
  for (ParamGroup g : kAllGroups) {
    const AdamGroupState state = gpu.DownloadState(g);
    EXPECT_EQ(cpu.state(g).exp_avg, state.exp_avg) << where << GroupName(g);
    EXPECT_EQ(cpu.state(g).exp_avg_sq, state.exp_avg_sq)
        << where << GroupName(g);
    EXPECT_EQ(cpu.state(g).step, state.step) << where << GroupName(g);
  }
}

// Runs both strategies over iterations 1..last from the same state and
// checks every event, the model, the moments and the saved state.
void RunParity(const GaussianModel& start, const DensityOptions& options,
               int64_t last, uint32_t seed, bool expect_all_kinds) {
  const double extent = 1.0;
  GaussianModel cpu_model = start;
  Adam cpu_adam(AdamOptions{}, extent);
  RandomMoments(cpu_model, seed, &cpu_adam);
  auto cpu = MakeInriaDensityStrategy(options, extent);
  cpu->Init(cpu_model);

  DeviceModel gpu_model(start);
  CudaAdam gpu_adam(AdamOptions{}, extent);
  gpu_adam.Init(start);
  for (ParamGroup g : kAllGroups) gpu_adam.UploadState(g, cpu_adam.state(g));
  CudaDensityControl gpu(options, extent);
  gpu.Init(start.size());

  bool densified = false, split = false, pruned = false;
  for (int64_t it = 1; it <= last; ++it) {
    const std::string where = "iteration " + std::to_string(it);
    ASSERT_EQ(cpu->WantsRadii(it), gpu.WantsRadii(it)) << where;
    ASSERT_EQ(cpu->MayChangeModel(it), gpu.MayChangeModel(it)) << where;
    ViewStats view(cpu_model.size(), seed * 1000 + uint32_t(it));
    const bool radii = cpu->WantsRadii(it);
    const GaussianModel before = cpu_model;
    const DensityEvent a = cpu->PostBackward(
        it, view.grads, radii ? &view.radii : nullptr, &cpu_model, &cpu_adam);
    const DensityEvent b = gpu.PostBackward(
        it, view.Arrays(), radii ? view.device_radii.data() : nullptr,
        gpu_model.Ref(), &gpu_adam);
    ASSERT_EQ(a.densified, b.densified) << where;
    ASSERT_EQ(a.opacity_reset, b.opacity_reset) << where;
    ASSERT_EQ(a.cloned, b.cloned) << where;
    ASSERT_EQ(a.split, b.split) << where;
    ASSERT_EQ(a.pruned, b.pruned) << where;
    std::vector<float> sample_scale(cpu_model.size(), 0.f);
    if (a.densified) {
      std::vector<int64_t> parent;
      gpu.DownloadParent(&parent);
      EXPECT_EQ(a.parent, parent) << where;
      sample_scale = SampleScales(before, cpu_model, a.parent);
      densified = true;
      split |= a.split > 0;
      pruned |= a.pruned > 0;
    }
    ExpectModelsMatch(cpu_model, gpu_model.Host(), sample_scale, where);
    ExpectMomentsMatch(cpu_adam, gpu_adam, where);
    ASSERT_EQ(cpu->SaveState(), gpu.SaveState()) << where;
  }
  if (expect_all_kinds) {
    EXPECT_TRUE(densified && split && pruned)
        << "the schedule must exercise clone, split and prune";
  }
}

TEST(CudaDensityTest, MatchesCpuStrategyOverIterations) {
  WATERGS_REQUIRE_CUDA();
  for (int sh_degree : {0, 3}) {
    SCOPED_TRACE("SH degree " + std::to_string(sh_degree));
    RunParity(RandomModel(3000, sh_degree, 5 + sh_degree), ShortSchedule(), 10,
              7 + sh_degree, true);
  }
}

TEST(CudaDensityTest, WhiteBackgroundResetAndSplitSamplesMatch) {
  WATERGS_REQUIRE_CUDA();
  RunParity(RandomModel(2000, 1, 11), WhiteBackgroundOptions(), 10, 13, false);
}

TEST(CudaDensityTest, OpacityResetIsIdentical) {
  WATERGS_REQUIRE_CUDA();
  DensityOptions options = ShortSchedule();
  options.densify_from_iter = 1000;  // reset only
  GaussianModel model = RandomModel(500, 2, 3);
  // Logits around the reset value's logit(0.01) ~ -4.6, and extremes.
  for (size_t i = 0; i < model.size(); ++i) {
    model.opacity_logits[i] = -4.6f + 0.001f * float(int(i % 200) - 100);
  }
  model.opacity_logits[0] = 60.f;
  model.opacity_logits[1] = -60.f;
  RunParity(model, options, 7, 21, false);
}

TEST(CudaDensityTest, EmptyModel) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel empty = RandomModel(0, 3, 1);
  DeviceModel gpu_model(empty);
  CudaAdam adam(AdamOptions{}, 1.0);
  adam.Init(empty);
  CudaDensityControl gpu(ShortSchedule(), 1.0);
  gpu.Init(0);
  for (int64_t it = 1; it <= 9; ++it) {
    const DensityEvent event = gpu.PostBackward(
        it, CudaGradientArrays{}, nullptr, gpu_model.Ref(), &adam);
    EXPECT_EQ(event.densified, it % 3 == 0);
    EXPECT_EQ(event.cloned + event.split + event.pruned, 0u);
  }
  EXPECT_EQ(gpu_model.means.size(), 0u);
  EXPECT_EQ(adam.size(), 0u);
}

TEST(CudaDensityTest, AllPrunedLeavesAnEmptyModelAsTheCpuDoes) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel model = RandomModel(700, 3, 9);
  for (float& logit : model.opacity_logits) logit = -20.f;
  DensityOptions options = ShortSchedule();
  RunParity(model, options, 3, 31, false);
  // RunParity checked sizes; confirm the CPU side really emptied.
  GaussianModel cpu_model = model;
  Adam adam(AdamOptions{}, 1.0);
  adam.Init(cpu_model);
  auto cpu = MakeInriaDensityStrategy(options, 1.0);
  cpu->Init(cpu_model);
  for (int64_t it = 1; it <= 3; ++it) {
    HostView view(cpu_model.size(), uint32_t(it));
    cpu->PostBackward(it, view.grads, nullptr, &cpu_model, &adam);
  }
  EXPECT_EQ(cpu_model.size(), 0u);
}

// 48M Gaussians at SH degree 3: sh_rest offsets (row x 45) pass 2^31 floats
// and the byte offsets pass 2^33. Everything is pruned but three rows near
// the end, which must arrive intact in order. No Adam (22 GB more).
TEST(CudaDensityTest, HugeModelIndexMath) {
  WATERGS_REQUIRE_CUDA();
  constexpr size_t kN = 48'000'000;
  constexpr int kRest = 45;
  size_t free_bytes = 0, total_bytes = 0;
  ASSERT_EQ(cudaMemGetInfo(&free_bytes, &total_bytes), cudaSuccess);
  if (free_bytes < (size_t(26) << 30)) {
    GTEST_SKIP() << "needs 26 GiB of free GPU memory";
  }
  GaussianModel empty;
  empty.sh_degree = 3;
  DeviceModel model(empty);
  model.means.Resize(3 * kN);
  model.log_scales.Resize(3 * kN);
  model.quats.Resize(4 * kN);
  model.sh_dc.Resize(3 * kN);
  model.sh_rest.Resize(kRest * kN);
  for (auto* buffer : {&model.means, &model.log_scales, &model.quats,
                       &model.sh_dc, &model.sh_rest}) {
    buffer->Zero();
  }
  std::vector<float> opacity(kN, -20.f);
  const size_t rows[] = {kN / 2, kN - 2, kN - 1};
  std::vector<float> rest(kRest);
  for (size_t r : rows) {
    opacity[r] = 1.f;
    for (int k = 0; k < kRest; ++k) rest[k] = float(r % 1000) + 0.01f * k;
    ASSERT_EQ(cudaMemcpy(model.sh_rest.data() + r * kRest, rest.data(),
                         kRest * sizeof(float), cudaMemcpyHostToDevice),
              cudaSuccess);
  }
  model.opacity_logits.Upload(opacity);
  DeviceBuffer<uint8_t> visible(kN);
  visible.Zero();
  DeviceBuffer<float> norms(kN);
  norms.Zero();
  CudaGradientArrays grads;
  grads.visible = visible.data();
  grads.mean2d_grad_norm_ndc = norms.data();

  CudaDensityControl gpu(ShortSchedule(), 1.0);
  gpu.Init(kN);
  const DensityEvent event =
      gpu.PostBackward(3, grads, nullptr, model.Ref(), nullptr);
  ASSERT_TRUE(event.densified);
  EXPECT_EQ(event.cloned + event.split, 0u);
  EXPECT_EQ(event.pruned, kN - 3);
  std::vector<int64_t> parent;
  gpu.DownloadParent(&parent);
  EXPECT_EQ(parent, (std::vector<int64_t>{int64_t(rows[0]), int64_t(rows[1]),
                                          int64_t(rows[2])}));
  const GaussianModel out = model.Host();
  ASSERT_EQ(out.size(), 3u);
  for (size_t j = 0; j < 3; ++j) {
    EXPECT_EQ(out.opacity_logits[j], 1.f);
    for (int k = 0; k < kRest; ++k) {
      EXPECT_EQ(out.sh_rest[j * kRest + k], float(rows[j] % 1000) + 0.01f * k)
          << "row " << j << " coefficient " << k;
    }
  }
  EXPECT_EQ(gpu.size(), 3u);
}

TEST(CudaDensityTest, ConstructingWithoutAGpuIsAOneLineError) {
  std::string why;
  if (CudaAvailable(&why)) GTEST_SKIP() << "a GPU is visible";
  try {
    CudaDensityControl control(ShortSchedule(), 1.0);
    FAIL() << "constructed without a GPU";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("CudaDensityControl"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

#endif  // WATERGS_WITH_CUDA

}  // namespace
}  // namespace watergs
