// Tests of the photometric refinement of registered cameras
// (plugin/photometric_refinement.h) on random textured scenes: it finds the
// camera a render was taken from, from a start off by pixels, with or
// without the right intrinsics, and leaves a camera alone when it cannot
// improve on it.
#include "plugin/photometric_refinement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>

#include "gaussian/depth_render.h"
#include "gaussian/device.h"
#include "tests/gaussian/rasterizer_test_scenes.h"
#include "watermark/evaluation.h"
#include "watermark/image_attacks.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

constexpr double kDepth = 4;  // the scenes' Gaussians lie at depth 2-6

struct Scene {
  RenderCamera truth = RandomCamera(160, 120, 7);
  GaussianModel model;
  std::unique_ptr<Rasterizer> rasterizer = MakeRasterizer(Device::kCpu);
  CameraRenderer render = [this](const RenderCamera& camera) {
    return RenderClamped(*rasterizer, model, camera, {0.f, 0.f, 0.f});
  };
  DepthRenderer depth_map = [this](const RenderCamera& camera) {
    return RenderDepth(*rasterizer, model, camera);
  };
  Scene() {
    SceneSpec spec;
    spec.count = 1500;
    spec.width = truth.width;
    spec.height = truth.height;
    spec.min_scale = 0.02;
    spec.max_scale = 0.08;
    spec.sh_degree = 0;
    model = RandomScene(truth, spec, 11);
  }
  // The render at the true camera, saved as JPEG 90 (a screenshot).
  ImageRGB Screenshot() {
    return ApplyImageAttack({ImageAttackKind::kJpeg, 90}, render(truth));
  }
};

TEST(PhotometricRefinement, EachParameterMovesTheImageByAboutOnePixel) {
  const RenderCamera camera = RandomCamera(160, 120, 3);
  for (int k = 0; k < 9; ++k) {
    double delta[9] = {0};
    delta[k] = 1;
    const double moved =
        CameraMotionPx(camera, MoveCamera(camera, kDepth, delta), kDepth);
    // Rolls and moves along the axis move corners by their distance from
    // the centre over the focal length (0.55 here), the rest 1 px or a
    // little more at a corner.
    EXPECT_GT(moved, 0.5) << k;
    EXPECT_LT(moved, 1.5) << k;
  }
  const double none[9] = {0};
  EXPECT_LT(CameraMotionPx(camera, MoveCamera(camera, kDepth, none), kDepth),
            1e-9);
}

TEST(PhotometricRefinement, FindsTheCameraAScreenshotWasTakenFrom) {
  Scene scene;
  const ImageRGB shot = scene.Screenshot();
  // A feature registration's error: pixels of rotation and translation.
  const double off[9] = {1.5, -1.0, 0.8, -1.2, 0.9, 1.0, 0, 0, 0};
  const RenderCamera start = MoveCamera(scene.truth, kDepth, off);
  const double before = CameraMotionPx(scene.truth, start, kDepth);
  ASSERT_GT(before, 2.0);
  const PhotometricResult r =
      RefinePhotometrically(shot, {start}, kDepth, scene.render);
  EXPECT_TRUE(r.applied);
  EXPECT_LT(r.rms_after, r.rms_before);
  EXPECT_LT(CameraMotionPx(scene.truth, r.camera, kDepth), 0.15)
      << "from " << before << " px";
  EXPECT_GT(r.renders, 10);
}

TEST(PhotometricRefinement, AnotherStartFarFromTheFirstWinsWhenTheRenderFits) {
  Scene scene;
  const ImageRGB shot = scene.Screenshot();
  // The first start: a registration a period off on repetitive texture,
  // far beyond the basin; a later one (another pose the matches support)
  // near the truth.
  const double far[9] = {40, -25, 10, 30, 20, -15, 0, 0, 0};
  const double near[9] = {1.2, -0.8, 0.5, -1.0, 0.7, 0.8, 0, 0, 0};
  const RenderCamera wrong = MoveCamera(scene.truth, kDepth, far);
  const RenderCamera right = MoveCamera(scene.truth, kDepth, near);
  ASSERT_GT(CameraMotionPx(wrong, scene.truth, kDepth),
            2 * PhotometricOptions().max_move_px);
  const PhotometricResult r =
      RefinePhotometrically(shot, {wrong, right}, kDepth, scene.render);
  EXPECT_TRUE(r.applied);
  EXPECT_LT(CameraMotionPx(scene.truth, r.camera, kDepth), 0.15);
  EXPECT_EQ(r.start, 1);
  EXPECT_LT(r.moved_px, 5) << "moved_px: from the start it left";
}

TEST(PhotometricRefinement, MovesTheIntrinsicsOnlyWhenTheyExplainTheImage) {
  Scene scene;
  const ImageRGB shot = scene.Screenshot();
  const double pose_off[9] = {1.0, -0.8, 0, 0.6, 0, 0, 0, 0, 0};
  // Started at the true intrinsics, they stay (their noise fit is refused).
  const RenderCamera right = MoveCamera(scene.truth, kDepth, pose_off);
  const PhotometricResult kept =
      RefinePhotometrically(shot, {right}, kDepth, scene.render);
  EXPECT_DOUBLE_EQ(kept.camera.fx, scene.truth.fx);
  EXPECT_DOUBLE_EQ(kept.camera.cx, scene.truth.cx);
  EXPECT_LT(CameraMotionPx(scene.truth, kept.camera, kDepth), 0.15);
  // A screenshot of a viewer with another field of view and a shifted
  // centre: the intrinsics move to it.
  const double zoom_off[9] = {1.0, -0.8, 0, 0.6, 0, 0, 3.0, 2.0, -1.5};
  const RenderCamera wrong = MoveCamera(scene.truth, kDepth, zoom_off);
  const PhotometricResult moved =
      RefinePhotometrically(shot, {wrong}, kDepth, scene.render);
  EXPECT_TRUE(moved.applied);
  EXPECT_NE(moved.camera.fx, wrong.fx);
  EXPECT_LT(CameraMotionPx(scene.truth, moved.camera, kDepth), 0.3);
  // The same with the right intrinsics among the starts: found by the pose
  // alone.
  const PhotometricResult second =
      RefinePhotometrically(shot, {wrong, right}, kDepth, scene.render);
  EXPECT_LT(CameraMotionPx(scene.truth, second.camera, kDepth), 0.15);
}

TEST(PhotometricRefinement, LeavesTheCameraWhenItCannotCompare) {
  Scene scene;
  ImageRGB shot = scene.Screenshot();
  const double off[9] = {1.0, 0, 0, 0, 0, 0, 0, 0, 0};
  const RenderCamera start = MoveCamera(scene.truth, kDepth, off);
  // No usable depth, or an image of another size: nothing rendered.
  for (double depth : {0.0, -1.0, double(NAN)}) {
    const PhotometricResult r =
        RefinePhotometrically(shot, {start}, depth, scene.render);
    EXPECT_FALSE(r.applied);
    EXPECT_EQ(r.renders, 0);
    EXPECT_DOUBLE_EQ(r.camera.R(0, 0), start.R(0, 0));
  }
  const ImageRGB small(80, 60);
  EXPECT_FALSE(
      RefinePhotometrically(small, {start}, kDepth, scene.render).applied);
  // An image of noise: whatever it finds stays within the allowed move and
  // finite.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0, 1);
  for (float& v : shot.data) v = u(rng);
  const PhotometricResult noise =
      RefinePhotometrically(shot, {start}, kDepth, scene.render);
  if (noise.applied) {
    EXPECT_LE(CameraMotionPx(start, noise.camera, kDepth),
              PhotometricOptions().max_move_px);
  }
  EXPECT_TRUE(std::isfinite(noise.rms_after));
}

// The image-gradient Jacobian against finite differences over renders (the
// other mode's Jacobian, steps of a quarter pixel) at a start off the truth:
// each of the 9 columns points the same way and has about the same length.
TEST(PhotometricRefinement, GradientJacobianAgreesWithRenders) {
  Scene scene;
  const double off[9] = {0.6, -0.4, 0.3, -0.5, 0.4, 0.5, 0.8, 0.5, -0.5};
  const RenderCamera start = MoveCamera(scene.truth, kDepth, off);
  const std::vector<float> depth_map = scene.depth_map(start);
  const double x[9] = {0.3, 0.2, -0.1, 0.2, -0.3, 0.1, 0.2, -0.2, 0.1};
  const std::vector<float> blurred =
      Blurred(scene.render(MoveCamera(start, kDepth, x)), 1.0);
  const std::vector<double> jacobian =
      GradientJacobian(blurred, depth_map, start, kDepth, x, 9);
  ASSERT_EQ(jacobian.size(), blurred.size() * 9);
  for (int j = 0; j < 9; ++j) {
    double y[9];
    std::copy(x, x + 9, y);
    y[j] += 0.25;
    const std::vector<float> moved =
        Blurred(scene.render(MoveCamera(start, kDepth, y)), 1.0);
    double dot = 0, fd_norm = 0, g_norm = 0;
    for (size_t i = 0; i < blurred.size(); ++i) {
      const double fd = (double(moved[i]) - double(blurred[i])) / 0.25;
      const double g = jacobian[i * 9 + j];
      ASSERT_TRUE(std::isfinite(g)) << i;
      dot += fd * g;
      fd_norm += fd * fd;
      g_norm += g * g;
    }
    EXPECT_GT(dot / std::sqrt(fd_norm * g_norm), 0.9) << "parameter " << j;
    EXPECT_NEAR(std::sqrt(g_norm / fd_norm), 1.0, 0.25) << "parameter " << j;
  }
}

// The refinement with the gradient Jacobian finds the same cameras as with
// finite differences (the three cases above) in at most half the renders
// (measured: 37 against 103 here; 2,265 against 4,758 and more on the
// demo's viewer screenshots, results/viewers/detect_cost).
TEST(PhotometricRefinement, GradientJacobianFindsTheCamerasInFewerRenders) {
  Scene scene;
  const ImageRGB shot = scene.Screenshot();
  PhotometricOptions gradient;
  gradient.depth_map = scene.depth_map;
  const double off[9] = {1.5, -1.0, 0.8, -1.2, 0.9, 1.0, 0, 0, 0};
  const RenderCamera start = MoveCamera(scene.truth, kDepth, off);
  const PhotometricResult by_renders =
      RefinePhotometrically(shot, {start}, kDepth, scene.render);
  const PhotometricResult r =
      RefinePhotometrically(shot, {start}, kDepth, scene.render, gradient);
  EXPECT_TRUE(by_renders.applied);
  EXPECT_TRUE(r.applied);
  EXPECT_LT(CameraMotionPx(scene.truth, r.camera, kDepth), 0.15);
  EXPECT_LT(CameraMotionPx(by_renders.camera, r.camera, kDepth), 0.2);
  EXPECT_LE(2 * r.renders, by_renders.renders)
      << r.renders << " renders against " << by_renders.renders;

  const double far[9] = {40, -25, 10, 30, 20, -15, 0, 0, 0};
  const double near[9] = {1.2, -0.8, 0.5, -1.0, 0.7, 0.8, 0, 0, 0};
  const PhotometricResult two =
      RefinePhotometrically(shot,
                            {MoveCamera(scene.truth, kDepth, far),
                             MoveCamera(scene.truth, kDepth, near)},
                            kDepth, scene.render, gradient);
  EXPECT_TRUE(two.applied);
  EXPECT_EQ(two.start, 1);
  EXPECT_LT(CameraMotionPx(scene.truth, two.camera, kDepth), 0.15);

  const double pose_off[9] = {1.0, -0.8, 0, 0.6, 0, 0, 0, 0, 0};
  const PhotometricResult kept =
      RefinePhotometrically(shot, {MoveCamera(scene.truth, kDepth, pose_off)},
                            kDepth, scene.render, gradient);
  EXPECT_DOUBLE_EQ(kept.camera.fx, scene.truth.fx);
  EXPECT_DOUBLE_EQ(kept.camera.cx, scene.truth.cx);
  EXPECT_LT(CameraMotionPx(scene.truth, kept.camera, kDepth), 0.15);
  const double zoom_off[9] = {1.0, -0.8, 0, 0.6, 0, 0, 3.0, 2.0, -1.5};
  const RenderCamera wrong = MoveCamera(scene.truth, kDepth, zoom_off);
  const PhotometricResult zoomed =
      RefinePhotometrically(shot, {wrong}, kDepth, scene.render, gradient);
  EXPECT_TRUE(zoomed.applied);
  EXPECT_NE(zoomed.camera.fx, wrong.fx);
  EXPECT_LT(CameraMotionPx(scene.truth, zoomed.camera, kDepth), 0.3);
  // A depth map of another size is not this camera's: finite differences.
  PhotometricOptions wrong_size;
  wrong_size.depth_map = [](const RenderCamera&) {
    return std::vector<float>(10, 4.f);
  };
  const PhotometricResult fallback =
      RefinePhotometrically(shot, {start}, kDepth, scene.render, wrong_size);
  EXPECT_EQ(fallback.renders, by_renders.renders + 2);  // + the 2 depth maps
  EXPECT_THROW(GradientJacobian(std::vector<float>(30), std::vector<float>(9),
                                scene.truth, kDepth, off, 9),
               std::invalid_argument);
}

}  // namespace
}  // namespace watergs
