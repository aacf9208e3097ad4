// Tests for the pieces of the GPU training step (cuda/cuda_training_step.h)
// that the trainer-level parity tests (trainer_test.cc) do not isolate: the
// screen radii the CUDA projection hands density control, and the host-step
// fallback of a CUDA trainer with compact moments. Each skips without a GPU.
//
// Tolerances. Radii are ceil(3 sqrt(lambda1)) of a 2D covariance computed in
// double on both sides; the device may contract to FMA, which moves lambda1
// by an ulp, so a radius exactly at an integer may round one pixel up or
// down: at most 1% of the radii may differ, each by at most 1 pixel.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/device.h"
#include "gaussian/projection.h"
#include "gaussian/trainer.h"
#include "tests/common/cuda_test.h"
#include "tests/common/look_at.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_rasterizer_device.h"
#endif

namespace watergs {
namespace {

TEST(CudaTrainingStep, ScreenRadiiMatchComputeScreenRadii) {
  WATERGS_REQUIRE_CUDA();
#ifdef WATERGS_WITH_CUDA
  for (unsigned seed : {1u, 2u, 3u}) {
    const RenderCamera cam = testing::RandomCamera(96, 64, seed);
    testing::SceneSpec spec;
    spec.count = 300;
    const GaussianModel model = testing::RandomScene(cam, spec, seed + 10);
    CudaRasterizer gpu;
    std::unique_ptr<RenderContext> context;
    ImageRGB image;
    gpu.Forward(model, cam, RenderOptions{}, &image, &context);
    GaussianGradients grads;
    grads.compact_sh = true;
    gpu.Backward(model, *context, ImageRGB(image.width, image.height), &grads);
    std::vector<float> device_radii, host_radii;
    gpu.DownloadScreenRadii(*context, &device_radii);
    ComputeScreenRadii(model, cam, grads.visible, &host_radii);
    ASSERT_EQ(device_radii.size(), model.size());
    ASSERT_EQ(host_radii.size(), model.size());
    size_t visible = 0, off_by_one = 0;
    for (size_t i = 0; i < model.size(); ++i) {
      visible += grads.visible[i];
      const float d = std::fabs(device_radii[i] - host_radii[i]);
      ASSERT_LE(d, 1.f) << "Gaussian " << i;
      off_by_one += d > 0;
      if (!grads.visible[i]) {
        EXPECT_EQ(device_radii[i], 0.f);
      }
    }
    EXPECT_GT(visible, model.size() / 4);  // the check is not vacuous
    EXPECT_LE(off_by_one, model.size() / 100);
  }
#endif
}

// Compact moments have no CUDA Adam: a CUDA trainer with them takes the
// host step (CUDA rasterizer through the host interface) and so the CPU
// trainer's steps, losses to float rounding.
TEST(CudaTrainingStep, CompactMomentsFallBackToTheHostStep) {
  WATERGS_REQUIRE_CUDA();
  InMemoryViews views;
  std::vector<size_t> train;
  const RenderCamera first = LookAtOrigin(Eigen::Vector3d(3, 0, 0.5), 40, 32);
  testing::SceneSpec spec;
  spec.sh_degree = 1;
  const GaussianModel truth = testing::RandomScene(first, spec, 4);
  auto cpu_rasterizer = MakeCpuRasterizer();
  for (int v = 0; v < 4; ++v) {
    const double a = 2 * M_PI * v / 4;
    const RenderCamera cam = LookAtOrigin(
        Eigen::Vector3d(3 * std::cos(a), 3 * std::sin(a), 0.5), 40, 32);
    ImageRGB image;
    cpu_rasterizer->Forward(truth, cam, RenderOptions{}, &image, nullptr);
    views.Add("view" + std::to_string(v), cam, image);
    train.push_back(v);
  }
  const GaussianModel init = testing::RandomScene(first, spec, 5);
  TrainerOptions o;
  o.iterations = 10;
  o.adam.compact_moments = true;
  o.adam.position_lr_max_steps = 10;
  Trainer cpu(o, views, train, init, 3.0, MakeCpuRasterizer());
  Trainer gpu(o, views, train, init, 3.0, MakeRasterizer(Device::kCuda));
  for (int i = 0; i < 3; ++i) {
    const IterationStats a = cpu.Step(), b = gpu.Step();
    EXPECT_NEAR(a.loss.total, b.loss.total, 1e-5 * (1 + a.loss.total));
  }
  EXPECT_EQ(gpu.model().CountNonFinite(), 0u);
  // The host Adam holds the compact moments: the host step ran.
  EXPECT_FALSE(gpu.adam().state(ParamGroup::kXyz).exp_avg_q.empty());
}

}  // namespace
}  // namespace watergs
