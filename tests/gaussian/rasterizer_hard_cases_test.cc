// Numerically hard inputs: outputs and gradients must stay finite, and the
// pathological Gaussians must not disturb the rest of the image.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/reference_rasterizer.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

size_t NonFinite(const std::vector<float>& v) {
  size_t n = 0;
  for (float x : v) n += std::isfinite(x) ? 0 : 1;
  return n;
}

// Forward + backward with a non-trivial upstream gradient; checks that the
// image and every gradient array are finite and returns the image.
ImageRGB RenderAndCheck(const GaussianModel& model, const RenderCamera& cam,
                        const RenderOptions& options = RenderOptions()) {
  auto rasterizer = MakeCpuRasterizer();
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  rasterizer->Forward(model, cam, options, &image, &context);
  EXPECT_EQ(NonFinite(image.data), 0u);
  ImageRGB grad(image.width, image.height);
  for (size_t k = 0; k < grad.data.size(); ++k) {
    grad.data[k] = (k % 5 == 0 ? -1.f : 0.5f);
  }
  GaussianGradients g;
  rasterizer->Backward(model, *context, grad, &g);
  for (const std::vector<float>* v :
       {&g.means, &g.log_scales, &g.quats, &g.opacity_logits, &g.sh_dc,
        &g.sh_rest, &g.mean2d_grad_norm, &g.mean2d_grad_norm_ndc}) {
    EXPECT_EQ(NonFinite(*v), 0u);
  }
  EXPECT_EQ(g.means.size(), model.means.size());
  EXPECT_EQ(g.sh_rest.size(), model.sh_rest.size());
  return image;
}

// Places Gaussian i at camera-frame point (x, y, z).
void PlaceAt(const RenderCamera& cam, GaussianModel* m, size_t i, double x,
             double y, double z) {
  const Eigen::Vector3d w =
      cam.R.transpose() * (Eigen::Vector3d(x, y, z) - cam.t);
  for (int k = 0; k < 3; ++k) m->means[3 * i + k] = static_cast<float>(w[k]);
}

TEST(RasterizerHardCases, PathologicalGaussiansStayFinite) {
  const RenderCamera cam = RandomCamera(64, 48, 1);
  SceneSpec spec;
  spec.count = 40;
  GaussianModel m = RandomScene(cam, spec, 2);
  const float inf = std::numeric_limits<float>::infinity();
  const float denormal = std::numeric_limits<float>::denorm_min();
  size_t i = 0;
  // Behind the camera, on / just beyond the near plane, at the camera centre.
  PlaceAt(cam, &m, i++, 0.1, 0.1, -1.0);
  PlaceAt(cam, &m, i++, 0.0, 0.0, cam.near_plane);
  PlaceAt(cam, &m, i++, 0.001, 0.0, cam.near_plane * 1.0001);
  PlaceAt(cam, &m, i++, 0.0, 0.0, 0.0);
  // At the image border and far outside it (Jacobian clamp).
  PlaceAt(cam, &m, i++, (0 - cam.cx) / cam.fx * 3, 0.0, 3.0);
  PlaceAt(cam, &m, i++, (cam.width - cam.cx) / cam.fx * 3, 0.2, 3.0);
  PlaceAt(cam, &m, i++, 40.0, -30.0, 2.0);
  // Zero, denormal and huge scales.
  for (float ls : {-inf, std::log(denormal), -80.f, 30.f, 88.f, inf}) {
    for (int k = 0; k < 3; ++k) m.log_scales[3 * i + k] = ls;
    ++i;
  }
  // Mixed extreme scales: a needle (near-singular 2D covariance).
  m.log_scales[3 * i] = 5, m.log_scales[3 * i + 1] = -40,
                   m.log_scales[3 * i + 2] = -40;
  ++i;
  m.log_scales[3 * i] = -25, m.log_scales[3 * i + 1] = 3,
                   m.log_scales[3 * i + 2] = -25;
  ++i;
  // Zero-norm and denormal quaternions.
  for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = 0;
  ++i;
  for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = denormal;
  ++i;
  // Opacity logits +-60.
  m.opacity_logits[i++] = 60;
  m.opacity_logits[i++] = -60;
  m.opacity_logits[i++] = 60;
  ASSERT_LE(i, m.size());
  for (unsigned pose = 0; pose < 3; ++pose) {
    RenderCamera view = cam;
    if (pose > 0) view = RandomCamera(64, 48, pose + 10);
    RenderAndCheck(m, view);
    RenderOptions crop;
    crop.rect = {0, 0, 17, 48};
    RenderAndCheck(m, view, crop);
  }
}

TEST(RasterizerHardCases, CulledGaussiansDoNotChangeTheImage) {
  const RenderCamera cam = RandomCamera(48, 32, 3);
  GaussianModel m = RandomScene(cam, SceneSpec(), 4);
  const ImageRGB before = RenderAndCheck(m, cam);
  GaussianModel extra = m;
  extra.Resize(m.size() + 2);
  PlaceAt(cam, &extra, m.size(), 0.0, 0.0, -2.0);      // Behind.
  PlaceAt(cam, &extra, m.size() + 1, 0.0, 0.0, 1e-5);  // Before near plane.
  for (size_t i = m.size(); i < extra.size(); ++i) {
    extra.opacity_logits[i] = 10;
    extra.quats[4 * i] = 1;
  }
  const ImageRGB after = RenderAndCheck(extra, cam);
  EXPECT_EQ(before.data, after.data);
}

TEST(RasterizerHardCases, HundredThousandGaussiansOnOneTile) {
  RenderCamera cam;
  cam.width = 16, cam.height = 16;
  cam.fx = cam.fy = 20, cam.cx = cam.cy = 8;
  GaussianModel m;
  m.sh_degree = 1;
  const size_t n = 100000;
  m.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    // Small jitter around the tile centre, depth 1-3, faint.
    m.means[3 * i] = 0.01f * std::sin(float(i));
    m.means[3 * i + 1] = 0.01f * std::cos(float(i));
    m.means[3 * i + 2] = 1.f + 2.f * float(i) / n;
    for (int k = 0; k < 3; ++k) m.log_scales[3 * i + k] = -3;
    m.quats[4 * i] = 1;
    m.opacity_logits[i] = i % 2 ? -4.f : -6.f;
    m.sh_dc[3 * i] = 1;
  }
  const ImageRGB image = RenderAndCheck(m, cam);
  // The stack is dense enough to hide the background at the centre.
  EXPECT_GT(image.At(8, 8)[0], 0.5f);
}

TEST(RasterizerHardCases, EmptyModelRendersBackground) {
  const RenderCamera cam = RandomCamera(20, 10, 5);
  GaussianModel m;
  m.sh_degree = 2;
  RenderOptions options;
  options.background = {0.25f, 0.5f, 0.75f};
  const ImageRGB image = RenderAndCheck(m, cam, options);
  ASSERT_EQ(image.data.size(), 600u);
  for (int k = 0; k < 600; ++k) {
    EXPECT_EQ(image.data[k], options.background[k % 3]);
  }
}

TEST(RasterizerHardCases, OnePixelImage) {
  RenderCamera cam;
  cam.width = cam.height = 1;
  cam.fx = cam.fy = 1, cam.cx = cam.cy = 0.5;
  SceneSpec spec;
  spec.count = 10;
  spec.margin = 0;
  const GaussianModel m = RandomScene(cam, spec, 6);
  const ImageRGB image = RenderAndCheck(m, cam);
  ASSERT_EQ(image.data.size(), 3u);
  const std::vector<double> ref =
      ReferenceRender(ReferenceModel::From(m), cam, RenderOptions());
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(image.data[ch], ref[ch], 1e-5);
}

}  // namespace
}  // namespace watergs
