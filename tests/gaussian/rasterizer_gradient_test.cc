// Whole-pipeline gradients of the fast rasterizer (float) against central
// finite differences through the double-precision reference twin, for every
// parameter group. The reference replays the discrete decisions of the base
// render (tile membership, 1/255 cut-off, early stop, depth order), so the
// differences see the same smooth piece that the backward differentiates
// instead of jumps of ~1/255 where a pixel crosses the cut-off.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/reference_rasterizer.h"
#include "gaussian/sh.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

// sum(weights * image) through the reference with frozen decisions.
double ReferenceLoss(const ReferenceModel& model, const RenderCamera& cam,
                     const RenderOptions& options,
                     const ReferenceDecisions& decisions,
                     const std::vector<double>& weights) {
  const std::vector<double> image =
      ReferenceRender(model, cam, options, &decisions);
  double loss = 0;
  for (size_t k = 0; k < image.size(); ++k) loss += weights[k] * image[k];
  return loss;
}

// Checks one parameter group: analytic (float) vs central differences of
// the reference (double) at step h.
void CheckGroup(const std::string& name,
                std::vector<double> ReferenceModel::*field,
                const std::vector<float>& analytic, const ReferenceModel& base,
                const RenderCamera& cam, const RenderOptions& options,
                const ReferenceDecisions& decisions,
                const std::vector<double>& weights) {
  const double h = 1e-5;
  ReferenceModel model = base;
  std::vector<double>& params = model.*field;
  ASSERT_EQ(params.size(), analytic.size()) << name;
  std::vector<double> numeric(params.size());
  double group_max = 0;
  for (size_t k = 0; k < params.size(); ++k) {
    const double saved = params[k];
    params[k] = saved + h;
    const double up = ReferenceLoss(model, cam, options, decisions, weights);
    params[k] = saved - h;
    const double down = ReferenceLoss(model, cam, options, decisions, weights);
    params[k] = saved;
    numeric[k] = (up - down) / (2 * h);
    group_max = std::max(group_max, std::abs(numeric[k]));
  }
  ASSERT_GT(group_max, 1e-3) << name << ": group has no gradient to check";
  // The backward sums per-pixel terms in float (~1e-6 relative each), so
  // errors scale with the group's gradient magnitude (measured ~1e-6 of
  // it), not with each entry's.
  for (size_t k = 0; k < params.size(); ++k) {
    EXPECT_NEAR(analytic[k], numeric[k],
                2e-5 * group_max + 1e-4 * std::abs(numeric[k]))
        << name << "[" << k << "]";
  }
}

// Renders with the fast rasterizer, back-propagates random pixel weights and
// compares every parameter group with finite differences.
void CheckScene(const GaussianModel& model, const RenderCamera& cam,
                const RenderOptions& options, unsigned seed) {
  auto rasterizer = MakeCpuRasterizer();
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  rasterizer->Forward(model, cam, options, &image, &context);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  ImageRGB grad_image(image.width, image.height);
  std::vector<double> weights(grad_image.data.size());
  for (size_t k = 0; k < weights.size(); ++k) {
    grad_image.data[k] = static_cast<float>(u(rng));
    weights[k] = grad_image.data[k];
  }
  GaussianGradients grads;
  rasterizer->Backward(model, *context, grad_image, &grads);
  const ReferenceModel ref = ReferenceModel::From(model);
  ReferenceDecisions decisions;
  ReferenceRender(ref, cam, options, nullptr, &decisions);
  CheckGroup("means", &ReferenceModel::means, grads.means, ref, cam, options,
             decisions, weights);
  CheckGroup("log_scales", &ReferenceModel::log_scales, grads.log_scales, ref,
             cam, options, decisions, weights);
  CheckGroup("quats", &ReferenceModel::quats, grads.quats, ref, cam, options,
             decisions, weights);
  CheckGroup("opacity_logits", &ReferenceModel::opacity_logits,
             grads.opacity_logits, ref, cam, options, decisions, weights);
  CheckGroup("sh_dc", &ReferenceModel::sh_dc, grads.sh_dc, ref, cam, options,
             decisions, weights);
  if (model.sh_degree > 0) {
    CheckGroup("sh_rest", &ReferenceModel::sh_rest, grads.sh_rest, ref, cam,
               options, decisions, weights);
  }
}

TEST(RasterizerGradient, MatchesFiniteDifferencesOnRandomScenes) {
  for (unsigned seed = 0; seed < 3; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const RenderCamera cam = RandomCamera(40, 34, 20 + seed);
    SceneSpec spec;
    spec.count = 14;
    spec.sh_degree = 3 - seed;
    const GaussianModel model = RandomScene(cam, spec, 30 + seed);
    RenderOptions options;
    options.background = {0.3f, 0.6f, 0.9f};
    CheckScene(model, cam, options, seed);
  }
}

TEST(RasterizerGradient, MatchesFiniteDifferencesUnderWebConventions) {
  // The render conventions with a backward pass: splats centred outside
  // 1.2x the frame dropped, SH capped at degree 1, the Jacobian unclamped;
  // means up to 14 px outside a 40 px frame, so some are dropped and some
  // sit beyond the 1.3 tan(half-FOV) clamp.
  for (unsigned seed = 0; seed < 2; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const RenderCamera cam = RandomCamera(40, 34, 60 + seed);
    SceneSpec spec;
    spec.count = 16;
    spec.margin = 14;
    const GaussianModel model = RandomScene(cam, spec, 70 + seed);
    RenderOptions options;
    options.conventions.cull_centre_outside = 1.2;
    options.conventions.max_sh_degree = 1;
    options.conventions.unclamped_jacobian = true;
    CheckScene(model, cam, options, 80 + seed);
  }
}

TEST(RasterizerGradient, OpaqueSceneWithEarlyStopAndAlphaCap) {
  // Opacities up to sigmoid(6): the 0.99 cap binds at centres and pixels
  // stop at T < 1e-4, both of which the backward must handle.
  const RenderCamera cam = RandomCamera(36, 30, 5);
  SceneSpec spec;
  spec.count = 16;
  spec.min_logit = 2, spec.max_logit = 6;
  spec.min_scale = 0.1, spec.max_scale = 0.4;
  const GaussianModel model = RandomScene(cam, spec, 6);
  RenderOptions options;
  options.background = {1, 1, 1};
  CheckScene(model, cam, options, 7);
}

TEST(RasterizerGradient, GaussiansOnTileBordersAndCrop) {
  const RenderCamera cam = RandomCamera(48, 40, 8);
  SceneSpec spec;
  spec.count = 12;
  GaussianModel model = RandomScene(cam, spec, 9);
  // Move the means onto tile corners and edges (pixel coords 16, 32).
  const double targets[][2] = {{16, 16},  {32, 16},  {16, 32},
                               {32.5, 8}, {8, 15.5}, {47.9, 16}};
  for (int i = 0; i < 6; ++i) {
    const double z = 2.5 + 0.4 * i;
    const Eigen::Vector3d xc((targets[i][0] - cam.cx) / cam.fx * z,
                             (targets[i][1] - cam.cy) / cam.fy * z, z);
    const Eigen::Vector3d xw = cam.R.transpose() * (xc - cam.t);
    for (int k = 0; k < 3; ++k) model.means[3 * i + k] = float(xw[k]);
  }
  CheckScene(model, cam, RenderOptions(), 10);
  RenderOptions crop;
  crop.rect = {9, 11, 25, 20};
  CheckScene(model, cam, crop, 11);
}

TEST(RasterizerGradient, DensificationStatisticIsMeanGradientNorm) {
  const RenderCamera cam = RandomCamera(40, 30, 12);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 13);
  auto rasterizer = MakeCpuRasterizer();
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  rasterizer->Forward(model, cam, RenderOptions(), &image, &context);
  ImageRGB grad_image(image.width, image.height);
  for (size_t k = 0; k < grad_image.data.size(); ++k) {
    grad_image.data[k] = (k % 7) * 0.1f - 0.3f;
  }
  GaussianGradients grads;
  rasterizer->Backward(model, *context, grad_image, &grads);
  // Finite differences of the loss w.r.t. a shift of one projected mean.
  const ReferenceModel ref = ReferenceModel::From(model);
  ReferenceDecisions decisions;
  ReferenceRender(ref, cam, RenderOptions(), nullptr, &decisions);
  std::vector<double> weights(grad_image.data.begin(), grad_image.data.end());
  int checked = 0;
  const double h = 1e-5;
  for (size_t i = 0; i < model.size(); ++i) {
    if (!grads.visible[i]) {
      EXPECT_EQ(grads.mean2d_grad_norm[i], 0.f);
      continue;
    }
    double g[2];
    for (int axis = 0; axis < 2; ++axis) {
      ReferenceModel m = ref;
      m.screen_offsets.assign(2 * model.size(), 0.0);
      m.screen_offsets[2 * i + axis] = h;
      const double up =
          ReferenceLoss(m, cam, RenderOptions(), decisions, weights);
      m.screen_offsets[2 * i + axis] = -h;
      const double down =
          ReferenceLoss(m, cam, RenderOptions(), decisions, weights);
      g[axis] = (up - down) / (2 * h);
    }
    const double norm = std::hypot(g[0], g[1]);
    const double ndc =
        std::hypot(g[0] * 0.5 * cam.width, g[1] * 0.5 * cam.height);
    EXPECT_NEAR(grads.mean2d_grad_norm[i], norm, 1e-3 * norm + 1e-6) << i;
    EXPECT_NEAR(grads.mean2d_grad_norm_ndc[i], ndc, 1e-3 * ndc + 1e-5) << i;
    checked += norm > 1e-3;
  }
  EXPECT_GT(checked, 10);
}

TEST(RasterizerGradient, SameResultForAnyThreadCount) {
  const RenderCamera cam = RandomCamera(90, 70, 14);
  SceneSpec spec;
  spec.count = 200;
  const GaussianModel model = RandomScene(cam, spec, 15);
  auto run = [&](int threads, ImageRGB* image, GaussianGradients* grads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    auto rasterizer = MakeCpuRasterizer();
    std::unique_ptr<RenderContext> context;
    rasterizer->Forward(model, cam, RenderOptions(), image, &context);
    ImageRGB grad(image->width, image->height);
    for (size_t k = 0; k < grad.data.size(); ++k) {
      grad.data[k] = std::sin(0.37f * k);
    }
    rasterizer->Backward(model, *context, grad, grads);
    omp_set_num_threads(saved);
  };
  ImageRGB image1, image3;
  GaussianGradients grads1, grads3;
  run(1, &image1, &grads1);
  run(3, &image3, &grads3);
  EXPECT_EQ(image1.data, image3.data);
  EXPECT_EQ(grads1.means, grads3.means);
  EXPECT_EQ(grads1.log_scales, grads3.log_scales);
  EXPECT_EQ(grads1.quats, grads3.quats);
  EXPECT_EQ(grads1.opacity_logits, grads3.opacity_logits);
  EXPECT_EQ(grads1.sh_dc, grads3.sh_dc);
  EXPECT_EQ(grads1.sh_rest, grads3.sh_rest);
  EXPECT_EQ(grads1.mean2d_grad_norm, grads3.mean2d_grad_norm);
}

// Factored SH gradients (GaussianGradients::compact_sh) expand to the dense
// ones, for every active degree; the other groups are unchanged.
TEST(RasterizerGradient, FactoredShGradientsExpandToTheDenseOnes) {
  const RenderCamera cam = RandomCamera(80, 60, 31);
  SceneSpec spec;
  spec.count = 120;
  const GaussianModel model = RandomScene(cam, spec, 32);
  const int stride = model.sh_rest_stride();
  for (int degree = 0; degree <= 3; ++degree) {
    auto rasterizer = MakeCpuRasterizer();
    RenderOptions options;
    options.active_sh_degree = degree;
    ImageRGB image;
    std::unique_ptr<RenderContext> context;
    rasterizer->Forward(model, cam, options, &image, &context);
    ImageRGB grad(image.width, image.height);
    for (size_t k = 0; k < grad.data.size(); ++k) {
      grad.data[k] = std::cos(0.11f * k);
    }
    GaussianGradients dense, factored;
    factored.compact_sh = true;
    rasterizer->Backward(model, *context, grad, &dense);
    rasterizer->Backward(model, *context, grad, &factored);
    EXPECT_TRUE(factored.sh_rest.empty());
    EXPECT_EQ(factored.sh_active_degree, degree);
    EXPECT_EQ(dense.means, factored.means);
    EXPECT_EQ(dense.quats, factored.quats);
    EXPECT_EQ(dense.mean2d_grad_norm_ndc, factored.mean2d_grad_norm_ndc);
    size_t nonzero = 0;
    for (size_t i = 0; i < model.size(); ++i) {
      float dc[3], rest[45];
      ShCoefficientGradients(factored.sh_active_degree,
                             &factored.sh_view_dir[3 * i],
                             &factored.sh_color_grad[3 * i], stride, dc, rest);
      for (int c = 0; c < 3; ++c) {
        const float want = dense.sh_dc[3 * i + c];
        EXPECT_NEAR(dc[c], want, 1e-6f * std::fabs(want) + 1e-12f) << i;
        nonzero += want != 0.f;
      }
      // The factors keep the view direction in float: the unit-bounded basis
      // moves by ~1e-7 (more, relatively, where a cubic term cancels), so the
      // bound scales with the colour gradient, not with each product.
      const float* g = &factored.sh_color_grad[3 * i];
      const float bound =
          1e-6f * (std::fabs(g[0]) + std::fabs(g[1]) + std::fabs(g[2])) +
          1e-12f;
      for (int k = 0; k < stride; ++k) {
        const float want = dense.sh_rest[i * stride + k];
        EXPECT_NEAR(rest[k], want, bound) << i << " " << k;
      }
    }
    EXPECT_GT(nonzero, 30u);
  }
}

}  // namespace
}  // namespace watergs
