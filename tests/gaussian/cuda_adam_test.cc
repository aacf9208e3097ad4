// Parity tests of the CUDA Adam (gaussian/cuda/cuda_adam.h) against the CPU
// Adam (gaussian/adam.h, itself checked against a double-precision
// reference in adam_test.cc): several steps of every parameter group from
// the same state, frozen groups and masks, factored SH gradients, the
// non-finite rejection rule, and moments following Gaussians. The GPU tests
// run when a GPU is visible.
//
// Tolerance: the kernel repeats AdamUpdate's float operations in order
// (unfused), and the factored SH expansion repeats ShBasis in double; they
// differ from the CPU only where GCC fuses a multiply-add: one float rounding
// per operation, which cancellation in m + w1 (g - m) can make large
// relative to a small result. So each value may differ by 4 float ulps of
// itself plus 1e-6 of the largest magnitude in its array; a wrong rate, bias
// correction or update term changes values by the update size (>= 1e-4 of
// the parameters here), orders of magnitude more.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_adam.h"
#endif

namespace watergs {
namespace {

#ifdef WATERGS_WITH_CUDA

constexpr ParamGroup kAllGroups[] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed) {
  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal;
  for (ParamGroup g : kAllGroups) {
    for (float& v : GroupParams(model, g)) v = normal(rng);
  }
  return model;
}

GaussianGradients RandomGrads(const GaussianModel& model, uint32_t seed) {
  GaussianGradients grads;
  grads.Reset(model.size(), model.sh_rest_stride());
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1e-2f);
  for (auto* v : {&grads.means, &grads.sh_dc, &grads.sh_rest,
                  &grads.opacity_logits, &grads.log_scales, &grads.quats}) {
    for (float& x : *v) x = normal(rng);
  }
  return grads;
}

// The same gradients with SH in factored form at SH degree `degree`.
GaussianGradients FactoredGrads(const GaussianModel& model, int degree,
                                uint32_t seed) {
  GaussianGradients grads = RandomGrads(model, seed);
  grads.sh_dc.clear();
  grads.sh_rest.clear();
  grads.compact_sh = true;
  grads.sh_active_degree = degree;
  std::mt19937 rng(seed + 1000);
  std::normal_distribution<float> normal(0.f, 1e-2f);
  grads.sh_color_grad.resize(3 * model.size());
  grads.sh_view_dir.resize(3 * model.size());
  for (float& x : grads.sh_color_grad) x = normal(rng);
  for (float& x : grads.sh_view_dir) x = 100 * normal(rng);
  for (int k = 0; k < 3; ++k) grads.sh_view_dir[k] = 0.f;  // degenerate
  return grads;
}

void ExpectClose(const std::vector<float>& cpu, const std::vector<float>& cuda,
                 const std::string& what) {
  ASSERT_EQ(cpu.size(), cuda.size()) << what;
  float scale = 0;
  for (float x : cpu) scale = std::max(scale, std::abs(x));
  size_t bad = 0;
  for (size_t j = 0; j < cpu.size(); ++j) {
    const double bound =
        4 * FLT_EPSILON * std::max(std::abs(cpu[j]), std::abs(cuda[j])) +
        1e-6 * scale;
    if (!(std::abs(double(cpu[j]) - cuda[j]) <= bound)) {
      if (++bad <= 5) {
        ADD_FAILURE() << what << "[" << j << "]: cpu " << cpu[j] << " cuda "
                      << cuda[j];
      }
    }
  }
  EXPECT_EQ(bad, 0u) << what;
}

void ExpectSameState(const Adam& cpu, const CudaAdam& cuda,
                     const GaussianModel& cpu_model,
                     const GaussianModel& cuda_model, const std::string& when) {
  ASSERT_EQ(cpu.size(), cuda.size()) << when;
  for (ParamGroup g : kAllGroups) {
    const std::string what = when + " " + GroupName(g);
    ExpectClose(GroupParams(cpu_model, g), GroupParams(cuda_model, g),
                what + " params");
    const AdamGroupState device = cuda.DownloadState(g);
    ExpectClose(cpu.state(g).exp_avg, device.exp_avg, what + " exp_avg");
    ExpectClose(cpu.state(g).exp_avg_sq, device.exp_avg_sq,
                what + " exp_avg_sq");
    EXPECT_EQ(cpu.state(g).step, device.step) << what;
  }
}

AdamOptions ShortSchedule() {
  AdamOptions options;
  options.position_lr_max_steps = 4;  // the position rate changes each step
  return options;
}

TEST(CudaAdam, StepsMatchCpuAdamForEveryGroup) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel cpu_model = RandomModel(1000, 3, 1);
  GaussianModel cuda_model = cpu_model;
  Adam cpu(ShortSchedule(), 2.5);
  CudaAdam cuda(ShortSchedule(), 2.5);
  cpu.Init(cpu_model);
  cuda.Init(cuda_model);
  for (int it = 1; it <= 6; ++it) {
    cpu.SetIteration(it);
    cuda.SetIteration(it);
    for (ParamGroup g : kAllGroups) {
      EXPECT_EQ(cpu.LearningRate(g), cuda.LearningRate(g));
    }
    if (it == 3) {  // a frozen group and a masked Gaussian, as embedding does
      cpu.SetGroupEnabled(ParamGroup::kOpacity, false);
      cuda.SetGroupEnabled(ParamGroup::kOpacity, false);
      std::vector<uint8_t> mask(1000, 1);
      mask[17] = 0;
      cpu.SetGaussianMask(ParamGroup::kXyz, mask);
      cuda.SetGaussianMask(ParamGroup::kXyz, mask);
    }
    if (it == 4) {
      cpu.SetGroupEnabled(ParamGroup::kOpacity, true);
      cuda.SetGroupEnabled(ParamGroup::kOpacity, true);
    }
    const GaussianGradients grads = RandomGrads(cpu_model, 10 + it);
    EXPECT_EQ(cpu.Step(grads, &cpu_model), 0u);
    EXPECT_EQ(cuda.Step(grads, &cuda_model), 0u);
    ExpectSameState(cpu, cuda, cpu_model, cuda_model,
                    "step " + std::to_string(it));
  }
  EXPECT_EQ(cuda.BytesPerGaussian(), cpu.BytesPerGaussian());
}

TEST(CudaAdam, FactoredShGradientsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  for (int degree : {0, 2, 3}) {
    GaussianModel cpu_model = RandomModel(300, 3, 2);
    GaussianModel cuda_model = cpu_model;
    Adam cpu(AdamOptions{}, 1.0);
    CudaAdam cuda(AdamOptions{}, 1.0);
    cpu.Init(cpu_model);
    cuda.Init(cuda_model);
    for (int it = 1; it <= 3; ++it) {
      const GaussianGradients grads = FactoredGrads(cpu_model, degree, 20 + it);
      EXPECT_EQ(cpu.Step(grads, &cpu_model), 0u);
      EXPECT_EQ(cuda.Step(grads, &cuda_model), 0u);
    }
    ExpectSameState(cpu, cuda, cpu_model, cuda_model,
                    "degree " + std::to_string(degree));
  }
}

TEST(CudaAdam, NonFiniteGradientsAreRejectedLikeCpu) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel cpu_model = RandomModel(50, 1, 3);
  GaussianModel cuda_model = cpu_model;
  Adam cpu(AdamOptions{}, 1.0);
  CudaAdam cuda(AdamOptions{}, 1.0);
  cpu.Init(cpu_model);
  cuda.Init(cuda_model);
  GaussianGradients grads = RandomGrads(cpu_model, 4);
  grads.means[1] = std::numeric_limits<float>::quiet_NaN();
  grads.opacity_logits[2] = std::numeric_limits<float>::infinity();
  grads.log_scales[0] = -std::numeric_limits<float>::infinity();
  grads.sh_rest[5] = std::numeric_limits<float>::quiet_NaN();
  grads.quats[7] = 3e38f;  // huge but finite: clamped, a bounded step
  const size_t rejected = cpu.Step(grads, &cpu_model);
  EXPECT_EQ(rejected, 4u);
  EXPECT_EQ(cuda.Step(grads, &cuda_model), rejected);
  EXPECT_EQ(cuda.rejected_total(), cpu.rejected_total());
  EXPECT_EQ(cuda_model.CountNonFinite(), 0u);
  ExpectSameState(cpu, cuda, cpu_model, cuda_model, "non-finite");
  // A parameter at the float limit: the update that would overflow is
  // skipped and counted, by both.
  cpu_model.means[4] = cuda_model.means[4] = -FLT_MAX;
  GaussianGradients push = RandomGrads(cpu_model, 5);
  push.means[4] = 1.f;  // Adam steps against the gradient: towards -inf
  cpu.SetLearningRate(ParamGroup::kXyz, 1e32);
  cuda.SetLearningRate(ParamGroup::kXyz, 1e32);
  const size_t pushed = cpu.Step(push, &cpu_model);
  EXPECT_GE(pushed, 1u);
  EXPECT_EQ(cuda.Step(push, &cuda_model), pushed);
  EXPECT_EQ(cuda_model.CountNonFinite(), 0u);
  ExpectSameState(cpu, cuda, cpu_model, cuda_model, "overflow");
}

TEST(CudaAdam, MomentsFollowFilterAppendAndGather) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel cpu_model = RandomModel(7, 2, 6);
  GaussianModel cuda_model = cpu_model;
  Adam cpu(AdamOptions{}, 1.0);
  CudaAdam cuda(AdamOptions{}, 1.0);
  cpu.Init(cpu_model);
  cuda.Init(cuda_model);
  std::vector<uint8_t> mask = {1, 0, 1, 1, 0, 1, 1};
  cpu.SetGaussianMask(ParamGroup::kScaling, mask);
  cuda.SetGaussianMask(ParamGroup::kScaling, mask);
  const GaussianGradients grads = RandomGrads(cpu_model, 7);
  cpu.Step(grads, &cpu_model);
  cuda.Step(grads, &cuda_model);
  // Density control: prune two, then append three clones (zero moments).
  const std::vector<bool> keep = {true, false, true, true, false, true, true};
  cpu.Filter(keep);
  cuda.Filter(keep);
  cpu_model.Filter(keep);
  cuda_model.Filter(keep);
  cpu.Append(3);
  cuda.Append(3);
  const GaussianModel survivors = cpu_model;
  for (size_t i : {0, 2, 3}) {
    cpu_model.AppendFrom(survivors, i);
    cuda_model.AppendFrom(survivors, i);
  }
  ASSERT_EQ(cuda.size(), 8u);
  ExpectSameState(cpu, cuda, cpu_model, cuda_model, "after filter+append");
  // The masks followed too: a step after that still matches.
  const GaussianGradients more = RandomGrads(cpu_model, 8);
  cpu.Step(more, &cpu_model);
  cuda.Step(more, &cuda_model);
  ExpectSameState(cpu, cuda, cpu_model, cuda_model, "step after resize");

  // A general gather: duplicates, reordering and fresh rows.
  const std::vector<int64_t> index = {5, 0, -1, 5, 7};
  std::vector<AdamGroupState> before;
  for (ParamGroup g : kAllGroups) before.push_back(cuda.DownloadState(g));
  cuda.Gather(index);
  ASSERT_EQ(cuda.size(), index.size());
  for (ParamGroup g : kAllGroups) {
    const int stride = GroupStride(cpu_model, g);
    const AdamGroupState after = cuda.DownloadState(g);
    const AdamGroupState& old = before[static_cast<int>(g)];
    ASSERT_EQ(after.exp_avg.size(), index.size() * stride);
    for (size_t i = 0; i < index.size(); ++i) {
      for (int k = 0; k < stride; ++k) {
        const float m = index[i] < 0 ? 0.f : old.exp_avg[index[i] * stride + k];
        const float v =
            index[i] < 0 ? 0.f : old.exp_avg_sq[index[i] * stride + k];
        EXPECT_EQ(after.exp_avg[i * stride + k], m) << GroupName(g);
        EXPECT_EQ(after.exp_avg_sq[i * stride + k], v) << GroupName(g);
      }
    }
    EXPECT_EQ(after.step, old.step);
  }
  EXPECT_THROW(cuda.Gather({0, 5}), Error);  // 5 is past the 5 Gaussians
  cuda.ResetMoments(ParamGroup::kOpacity);
  for (float m : cuda.DownloadState(ParamGroup::kOpacity).exp_avg_sq) {
    EXPECT_EQ(m, 0.f);
  }
}

TEST(CudaAdam, ResumesFromCpuState) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel cpu_model = RandomModel(40, 1, 9);
  Adam cpu(AdamOptions{}, 1.0);
  cpu.Init(cpu_model);
  for (int it = 0; it < 3; ++it)
    cpu.Step(RandomGrads(cpu_model, 30 + it), &cpu_model);
  GaussianModel cuda_model = cpu_model;
  CudaAdam cuda(AdamOptions{}, 1.0);
  cuda.Init(cuda_model);
  for (ParamGroup g : kAllGroups) cuda.UploadState(g, cpu.state(g));
  const GaussianGradients grads = RandomGrads(cpu_model, 40);
  cpu.Step(grads, &cpu_model);
  cuda.Step(grads, &cuda_model);
  ExpectSameState(cpu, cuda, cpu_model, cuda_model, "resumed");
  AdamGroupState wrong;
  wrong.exp_avg.resize(3);
  EXPECT_THROW(cuda.UploadState(ParamGroup::kXyz, wrong), Error);
}

TEST(CudaAdam, MismatchedGradientsAreAnError) {
  WATERGS_REQUIRE_CUDA();
  GaussianModel model = RandomModel(3, 0, 11);
  CudaAdam adam(AdamOptions{}, 1.0);
  adam.Init(model);
  GaussianGradients grads;
  grads.Reset(2, 0);
  EXPECT_THROW(adam.Step(grads, &model), Error);
  GaussianModel bigger = RandomModel(4, 0, 12);
  EXPECT_THROW(adam.Step(RandomGrads(bigger, 13), &bigger), Error);
}

// Needs no GPU: the refusal comes before any device call.
TEST(CudaAdam, RefusesCpuOnlyMomentLayouts) {
  AdamOptions compact;
  compact.compact_moments = true;
  AdamOptions half;
  half.half_moments = true;
  for (const AdamOptions& options : {compact, half}) {
    try {
      CudaAdam adam(options, 1.0);
      ADD_FAILURE() << "CudaAdam accepted a CPU-only moment layout";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("CPU-only"), std::string::npos)
          << e.what();
    }
  }
}

#else

TEST(CudaAdam, SkippedWithoutCudaBackend) { WATERGS_REQUIRE_CUDA(); }

#endif

}  // namespace
}  // namespace watergs
