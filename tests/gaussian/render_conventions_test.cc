// Render conventions (gaussian/render_conventions.h) in the CPU forward
// pass: each one changes only what it names, at a value that changes
// nothing it renders bit-identically to the default, the registry's names
// resolve, and what has no backward or no CUDA twin refuses in one line.
#include "gaussian/render_conventions.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/reference_rasterizer.h"
#include "gaussian/sh.h"
#include "gaussian/util/error.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

ImageRGB Render(const GaussianModel& model, const RenderCamera& camera,
                const RenderConventions& conventions,
                std::unique_ptr<RenderContext>* context = nullptr) {
  RenderOptions options;
  options.conventions = conventions;
  ImageRGB image;
  MakeCpuRasterizer()->Forward(model, camera, options, &image, context);
  return image;
}

// A 64x48 camera at the origin looking down +z, its principal point on the
// centre of pixel (32, 24).
RenderCamera AxisCamera() {
  RenderCamera camera;
  camera.width = 64, camera.height = 48;
  camera.fx = camera.fy = 50;
  camera.cx = 32.5, camera.cy = 24.5;
  camera.R = Eigen::Matrix3d::Identity();
  camera.t = Eigen::Vector3d::Zero();
  return camera;
}

// One isotropic Gaussian of SH degree 0 centred on pixel (px, py) (its
// centre px + 0.5, py + 0.5), depth 4, of
// standard deviation `sigma_px` pixels there, opacity 0.5, base colour
// `base` in every channel.
GaussianModel OneSplat(double px, double py, double sigma_px,
                       double base = 0.5) {
  const RenderCamera camera = AxisCamera();
  const double z = 4;
  GaussianModel model;
  model.sh_degree = 0;
  model.Resize(1);
  model.means = {float((px + 0.5 - camera.cx) / camera.fx * z),
                 float((py + 0.5 - camera.cy) / camera.fy * z), float(z)};
  const float log_scale = float(std::log(sigma_px * z / camera.fx));
  model.log_scales = {log_scale, log_scale, log_scale};
  model.quats = {1, 0, 0, 0};
  model.opacity_logits = {0};
  for (int ch = 0; ch < 3; ++ch) model.sh_dc[ch] = float((base - 0.5) / kShC0);
  return model;
}

double Lit(const ImageRGB& image) {
  double sum = 0;
  for (float v : image.data) sum += v;
  return sum;
}

float Red(const ImageRGB& image, int x, int y) {
  return image.data[3 * (size_t(y) * image.width + x)];
}

RenderConventions Web() {
  return FindRenderConventions("web", "test").conventions;
}

TEST(RenderConventions, RegistryNamesWatergsFirstAndTheMeasuredWebSet) {
  const auto& registry = RenderConventionsRegistry();
  ASSERT_GE(registry.size(), 2u);
  EXPECT_EQ(registry[0].name, "watergs");
  EXPECT_TRUE(registry[0].conventions.IsDefault());
  for (size_t a = 0; a < registry.size(); ++a) {
    EXPECT_FALSE(registry[a].description.empty());
    for (size_t b = a + 1; b < registry.size(); ++b) {
      EXPECT_NE(registry[a].name, registry[b].name);
    }
  }
  const RenderConventions web = Web();
  EXPECT_EQ(web.cull_centre_outside, 1.2);
  EXPECT_EQ(web.max_sh_degree, 0);
  EXPECT_TRUE(web.clamp_base_color);
  EXPECT_EQ(web.extent_cap_px, 0);
  EXPECT_EQ(web.eigen_gap_floor, 0.1);
  EXPECT_EQ(web.falloff, Falloff::kCutAt8);
  EXPECT_TRUE(web.base_opacity_8bit);
  EXPECT_TRUE(web.composite_8bit);
  EXPECT_FALSE(web.compact_work_buffer);
  const RenderConventions playcanvas =
      FindRenderConventions("playcanvas", "test").conventions;
  EXPECT_EQ(playcanvas.min_extent_px, 1);
  EXPECT_TRUE(playcanvas.composite_8bit);
  EXPECT_TRUE(playcanvas.compact_work_buffer);
  EXPECT_FALSE(playcanvas.base_opacity_8bit);
  EXPECT_EQ(RenderConventionNames(), "watergs|web|playcanvas");
  try {
    FindRenderConventions("webb", "--reference_conventions");
    FAIL() << "an unknown name was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--reference_conventions: unknown render conventions 'webb' "
              "(one of watergs, web, playcanvas)");
  }
}

TEST(RenderConventions, ValuesThatChangeNothingRenderBitIdentically) {
  for (unsigned seed = 0; seed < 4; ++seed) {
    const RenderCamera camera = RandomCamera(70, 52, seed);
    SceneSpec spec;
    spec.sh_degree = 3;
    const GaussianModel model = RandomScene(camera, spec, 40 + seed);
    const ImageRGB plain = Render(model, camera, RenderConventions());
    ASSERT_GT(Lit(plain), 1.0);
    RenderConventions wide;
    wide.cull_centre_outside = 1e6;  // every centre is inside
    EXPECT_EQ(Render(model, camera, wide).data, plain.data) << seed;
    RenderConventions all_bands;
    all_bands.max_sh_degree = 3;
    EXPECT_EQ(Render(model, camera, all_bands).data, plain.data) << seed;
  }
  // No base colour outside [0, 1], no splat wider than the frame: the clamp
  // and the cap change nothing.
  const GaussianModel small = OneSplat(30, 20, 3.0, 0.8);
  const ImageRGB plain = Render(small, AxisCamera(), RenderConventions());
  RenderConventions clamp_and_cap;
  clamp_and_cap.clamp_base_color = true;
  clamp_and_cap.extent_cap_px = 1024;
  EXPECT_EQ(Render(small, AxisCamera(), clamp_and_cap).data, plain.data);
}

TEST(RenderConventions, WebDropsASplatCentredOutsideTheFrameItReaches) {
  // Centre at NDC x = 1.32 (outside gaussian-splats-3d's 1.2 limit), 12 px
  // wide: its footprint covers the right third of the frame.
  const GaussianModel outside = OneSplat(1.15 * 64, 24, 12);
  ASSERT_GT(Lit(Render(outside, AxisCamera(), RenderConventions())), 10.0);
  EXPECT_EQ(Lit(Render(outside, AxisCamera(), Web())), 0.0);
  // At NDC x = 1.12 it stays.
  const GaussianModel inside = OneSplat(1.05 * 64, 24, 12);
  EXPECT_GT(Lit(Render(inside, AxisCamera(), Web())), 10.0);
  // Vertically too, and the limit is a parameter.
  const GaussianModel below = OneSplat(32, 1.2 * 48, 12);
  RenderConventions wide;
  wide.cull_centre_outside = 1.5;
  EXPECT_GT(Lit(Render(below, AxisCamera(), wide)), 10.0);
  wide.cull_centre_outside = 1.3;
  EXPECT_EQ(Lit(Render(below, AxisCamera(), wide)), 0.0);
}

TEST(RenderConventions, ShCapIgnoresTheHigherBands) {
  const RenderCamera camera = RandomCamera(48, 40, 5);
  SceneSpec spec;
  spec.sh_degree = 3;
  GaussianModel model = RandomScene(camera, spec, 9);
  RenderConventions cap;
  cap.max_sh_degree = 0;
  const ImageRGB capped = Render(model, camera, cap);
  RenderOptions degree0;
  degree0.active_sh_degree = 0;
  ImageRGB expected;
  MakeCpuRasterizer()->Forward(model, camera, degree0, &expected, nullptr);
  EXPECT_EQ(capped.data, expected.data);
  EXPECT_NE(capped.data, Render(model, camera, RenderConventions()).data);
  // The tighter of the two caps wins.
  cap.max_sh_degree = 2;
  RenderOptions degree1;
  degree1.active_sh_degree = 1;
  degree1.conventions = cap;
  ImageRGB both;
  MakeCpuRasterizer()->Forward(model, camera, degree1, &both, nullptr);
  degree1.conventions = RenderConventions();
  MakeCpuRasterizer()->Forward(model, camera, degree1, &expected, nullptr);
  EXPECT_EQ(both.data, expected.data);
}

TEST(RenderConventions, BaseColourIsClampedToOneBeforeTheHigherBands) {
  // Base colour 1.4 (10% of the demo's splats are brighter than 1): the
  // centre pixel is 0.5 x 1.4 without the clamp, 0.5 x 1 with it.
  const GaussianModel bright = OneSplat(32, 24, 4, 1.4);
  RenderConventions clamp;
  clamp.clamp_base_color = true;
  EXPECT_NEAR(Red(Render(bright, AxisCamera(), RenderConventions()), 32, 24),
              0.7, 1e-4);
  EXPECT_NEAR(Red(Render(bright, AxisCamera(), clamp), 32, 24), 0.5, 1e-4);
  // Below 0 it clamps at 0 either way (Inria's colour clamp).
  const GaussianModel dark = OneSplat(32, 24, 4, -0.3);
  EXPECT_EQ(Red(Render(dark, AxisCamera(), clamp), 32, 24), 0.f);
  // The higher bands are added after the clamp: degree 1 with a constant
  // +0.2 along the view direction (+z) on top of the clamped 1.
  GaussianModel banded = bright;
  banded.sh_degree = 1;
  banded.sh_rest.assign(size_t(banded.sh_rest_stride()), 0.f);
  // Basis 2 is C1 z; the splat sits on the axis (z = 1).
  for (int ch = 0; ch < 3; ++ch) banded.sh_rest[3 + ch] = float(0.2 / kShC1);
  EXPECT_NEAR(Red(Render(banded, AxisCamera(), clamp), 32, 24), 0.6, 1e-4);
  EXPECT_NEAR(Red(Render(banded, AxisCamera(), RenderConventions()), 32, 24),
              0.8, 1e-4);
}

TEST(RenderConventions, BaseColourAndOpacityFlooredToEightBits) {
  // gaussian-splats-3d stores floor(255 v): base 0.3 -> 76/255, opacity
  // 0.5 -> 127/255; the centre pixel is their product.
  RenderConventions eight_bit;
  eight_bit.base_opacity_8bit = true;
  const GaussianModel splat = OneSplat(32, 24, 4, 0.3);
  EXPECT_NEAR(Red(Render(splat, AxisCamera(), RenderConventions()), 32, 24),
              0.15, 1e-5);
  EXPECT_NEAR(Red(Render(splat, AxisCamera(), eight_bit), 32, 24),
              76.0 / 255 * 127.0 / 255, 1e-5);
  // Above 1 the stored base colour is 255/255 (the clamp comes with it).
  EXPECT_NEAR(
      Red(Render(OneSplat(32, 24, 4, 1.4), AxisCamera(), eight_bit), 32, 24),
      127.0 / 255, 1e-5);
  EXPECT_EQ(StoredOpacity(0.999, eight_bit), 254.0 / 255);
  EXPECT_EQ(StoredBaseColor(-0.2, eight_bit), 0.0);
  EXPECT_EQ(StoredBaseColor(0.3, RenderConventions()), 0.3);
}

// `front` in front of `back` (depth 4 and 5), both centred on pixel (32, 24)
// with a standard deviation of 4 px, black background.
GaussianModel TwoStacked(double front_base, double front_opacity,
                         double back_base, double back_opacity) {
  GaussianModel model = OneSplat(32, 24, 4, front_base);
  const GaussianModel back = OneSplat(32, 24, 4, back_base);
  model.Resize(2);
  for (int d = 0; d < 3; ++d) {
    model.means[3 + d] = back.means[d] * 1.25f;  // depth 5, same pixel
    model.log_scales[3 + d] = back.log_scales[d] + float(std::log(1.25));
    model.sh_dc[3 + d] = back.sh_dc[d];
  }
  for (int d = 0; d < 4; ++d) model.quats[4 + d] = back.quats[d];
  auto logit = [](double o) { return float(std::log(o / (1 - o))); };
  model.opacity_logits = {logit(front_opacity), logit(back_opacity)};
  return model;
}

TEST(RenderConventions, EightBitCompositeSaturatesABrightSplatBehind) {
  // At the centre: the back splat (colour 1.8, alpha 0.9) adds 1.62, the
  // front one (0.2, 0.5) covers half of it. Inria sums in float and clamps
  // once: 0.1 + 0.5 x 1.62 = 0.91. A WebGL canvas blends back to front in
  // 8 bits: the back splat saturates at 1, then 0.1 + 0.5 x 1 = 0.6.
  const GaussianModel stacked = TwoStacked(0.2, 0.5, 1.8, 0.9);
  RenderConventions composite;
  composite.composite_8bit = true;
  EXPECT_NEAR(Red(Render(stacked, AxisCamera(), RenderConventions()), 32, 24),
              0.91, 1e-4);
  EXPECT_NEAR(Red(Render(stacked, AxisCamera(), composite), 32, 24), 0.6, 1e-6);
  // Every blend is stored in 8 bits: one splat of 0.3 at alpha 0.5 gives
  // round(255 x 0.15) = 38 levels, and every pixel is a whole level.
  const ImageRGB single =
      Render(OneSplat(32, 24, 4, 0.3), AxisCamera(), composite);
  EXPECT_NEAR(Red(single, 32, 24), 38.0 / 255, 1e-6);
  for (float v : single.data) {
    EXPECT_NEAR(v * 255, std::round(v * 255), 1e-3);
  }
  // The background is stored first, halves up: 0.3 is 76.5 levels in float,
  // 77 where no splat reaches.
  RenderOptions grey;
  grey.conventions = composite;
  grey.background = {0.3f, 0.3f, 0.3f};
  ImageRGB on_grey;
  MakeCpuRasterizer()->Forward(OneSplat(32, 24, 2, 0.3), AxisCamera(), grey,
                               &on_grey, nullptr);
  EXPECT_NEAR(Red(on_grey, 0, 0), 77.0 / 255, 1e-6);
  // Without colours above 1 it differs from Inria's sum by the rounding
  // alone: half a level at each of two roundings, shrunk by the blends
  // after them, under a level in all.
  const GaussianModel dim = TwoStacked(0.2, 0.5, 0.7, 0.9);
  const ImageRGB inria = Render(dim, AxisCamera(), RenderConventions());
  const ImageRGB eight = Render(dim, AxisCamera(), composite);
  for (size_t k = 0; k < inria.data.size(); ++k) {
    EXPECT_NEAR(eight.data[k], inria.data[k], 1.0 / 255 + 1e-6) << k;
  }
}

TEST(RenderConventions, CompactWorkBufferPacksAsPlayCanvasDoes) {
  // Scales: ln s on 255 levels of 21/255 over [-12, 9].
  const double step = 21.0 / 255;
  double log_scale[3] = {-12 + 100 * step + 0.3 * step,
                         -12 + 40 * step - 0.4 * step, -40};
  double quat[4] = {-0.9, 0.1, -0.3, 0.2};
  double opacity = 0.5;
  CompactSplat(log_scale, quat, &opacity);
  EXPECT_NEAR(log_scale[0], -12 + 100 * step, 1e-12);
  EXPECT_NEAR(log_scale[1], -12 + 40 * step, 1e-12);
  EXPECT_EQ(log_scale[2], -30);  // under 1e-10: level 0, no size
  // Above 1e-10 but below e^-12 the lowest level is 1, above e^9 the top.
  double edges[3] = {-15, 12, -12 + 255 * step};
  double unit_quat[4] = {1, 0, 0, 0};
  double full = 1;
  CompactSplat(edges, unit_quat, &full);
  EXPECT_NEAR(edges[0], -12 + step, 1e-12);
  EXPECT_NEAR(edges[1], 9, 1e-12);
  EXPECT_NEAR(edges[2], 9, 1e-12);
  EXPECT_EQ(full, 1.0);
  // The identity's p = 0 sits between levels 1023 and 1024 of 2047 (x, y)
  // and 511 and 512 of 1023 (z): each rounds up, half a step off 0.
  EXPECT_NEAR(
      unit_quat[1],
      std::sqrt(2 - 2 * std::pow(1.0 / 2047, 2) - std::pow(1.0 / 1023, 2)) / 1 *
          (1.0 / 2047),
      1e-12);
  EXPECT_NEAR(unit_quat[3], unit_quat[1] * 2047.0 / 1023, 1e-12);
  // The rotation: unit, w >= 0, the input's (sign flipped) within the
  // 11/11/10-bit steps.
  const double norm = std::sqrt(0.81 + 0.01 + 0.09 + 0.04);
  const double expected[4] = {0.9 / norm, -0.1 / norm, 0.3 / norm, -0.2 / norm};
  double unit = 0;
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(quat[k], expected[k], 2e-3) << k;
    unit += quat[k] * quat[k];
  }
  EXPECT_NEAR(unit, 1, 1e-12);
  EXPECT_EQ(opacity, 128.0 / 255);  // round(127.5)
  EXPECT_EQ(CompactColor(1.0, 0), 512 * 4.0 / 2047);
  EXPECT_EQ(CompactColor(1.0, 2), 256 * 4.0 / 1023);
  EXPECT_EQ(CompactColor(5.0, 1), 4.0);
  EXPECT_EQ(CompactColor(-0.1, 1), 0.0);
  // A splat whose scale lies between two levels is drawn at the nearer.
  RenderConventions compact;
  compact.compact_work_buffer = true;
  GaussianModel between = OneSplat(32, 24, 3, 0.5);
  const double level = std::floor((between.log_scales[0] + 12) / step + 0.5);
  GaussianModel on_level = between;
  for (float& v : on_level.log_scales) v = float(-12 + level * step);
  EXPECT_NE(Render(between, AxisCamera(), RenderConventions()).data,
            Render(on_level, AxisCamera(), RenderConventions()).data);
  const ImageRGB packed = Render(between, AxisCamera(), compact);
  const ImageRGB packed_on_level = Render(on_level, AxisCamera(), compact);
  for (size_t k = 0; k < packed.data.size(); ++k) {
    EXPECT_NEAR(packed.data[k], packed_on_level.data[k], 1e-6) << k;
  }
}

TEST(RenderConventions, ExtentCapShrinksWideSplatsAlongTheirWideAxisOnly) {
  // A splat 200 px wide along an axis 30 degrees from x, 3 px across, in a
  // 64x48 frame: PlayCanvas' cap min(1024, 48) limits 2 sqrt(2 lambda) to
  // 48 px, lambda to 288 px^2 along the wide axis; the narrow axis keeps
  // 3^2 + 0.3 (the dilation).
  GaussianModel model = OneSplat(32, 24, 3.0);
  const double theta = M_PI / 6;
  model.quats = {float(std::cos(theta / 2)), 0, 0, float(std::sin(theta / 2))};
  model.log_scales[0] = float(std::log(200.0 * 4 / 50));
  RenderConventions cap;
  cap.extent_cap_px = 1024;
  const ImageRGB capped = Render(model, AxisCamera(), cap);
  const ImageRGB plain = Render(model, AxisCamera(), RenderConventions());
  const double wide = 288, narrow = 9.3, wide_plain = 200.0 * 200 + 0.3;
  auto expected = [&](int x, int y, double along) {
    const double dx = x - 32, dy = y - 24;
    const double u = dx * std::cos(theta) + dy * std::sin(theta);
    const double v = -dx * std::sin(theta) + dy * std::cos(theta);
    const double alpha =
        0.5 * std::exp(-0.5 * (u * u / along + v * v / narrow));
    return 0.5 * alpha;  // base colour 0.5
  };
  for (const auto& [x, y] :
       {std::pair{32, 24}, {52, 36}, {12, 12}, {40, 29}, {33, 26}}) {
    EXPECT_NEAR(Red(capped, x, y), expected(x, y, wide), 2e-4) << x << "," << y;
    EXPECT_NEAR(Red(plain, x, y), expected(x, y, wide_plain), 2e-4)
        << x << "," << y;
  }
  EXPECT_LT(Red(capped, 52, 36), Red(plain, 52, 36) - 0.01);
}

TEST(RenderConventions, EigenGapFloorStretchesNearRoundSplatsVertically) {
  // A round splat of 0.5 px sigma: its dilated covariance 0.55 I has equal
  // eigenvalues; gaussian-splats-3d splits them by 2 sqrt(0.1) and takes the
  // major axis along normalize(b, lambda1 - a) = (0, 1): vertical.
  const GaussianModel round = OneSplat(32, 24, 0.5);
  RenderConventions floor;
  floor.eigen_gap_floor = 0.1;
  const double major = 0.55 + std::sqrt(0.1), minor = 0.55 - std::sqrt(0.1);
  const ImageRGB floored = Render(round, AxisCamera(), floor);
  EXPECT_NEAR(Red(floored, 33, 24), 0.25 * std::exp(-0.5 / minor), 1e-5);
  EXPECT_NEAR(Red(floored, 32, 25), 0.25 * std::exp(-0.5 / major), 1e-5);
  const ImageRGB plain = Render(round, AxisCamera(), RenderConventions());
  EXPECT_NEAR(Red(plain, 33, 24), Red(plain, 32, 25), 1e-6);
  EXPECT_LT(Red(floored, 33, 24), Red(plain, 33, 24) - 0.02);
  // A splat far below a pixel: 0.3 + s^2 < sqrt(0.1) leaves the minor
  // eigenvalue at or below 0, and the viewer draws nothing.
  const GaussianModel dot = OneSplat(32, 24, 0.05);
  EXPECT_GT(Lit(Render(dot, AxisCamera(), RenderConventions())), 0.01);
  EXPECT_EQ(Lit(Render(dot, AxisCamera(), floor)), 0.0);
  // An elongated splat (eigenvalues 9.3 and 1.3 px^2, 30 degrees from x)
  // is past the floor: the same ellipse.
  GaussianModel long_splat = OneSplat(32, 24, 1.0);
  const double theta = M_PI / 6;
  long_splat.quats = {float(std::cos(theta / 2)), 0, 0,
                      float(std::sin(theta / 2))};
  long_splat.log_scales[0] = float(std::log(3.0 * 4 / 50));
  const ImageRGB a = Render(long_splat, AxisCamera(), floor);
  const ImageRGB b = Render(long_splat, AxisCamera(), RenderConventions());
  for (size_t k = 0; k < a.data.size(); ++k) {
    ASSERT_NEAR(a.data[k], b.data[k], 1e-6) << k;
  }
}

TEST(RenderConventions, MinExtentDropsSplatsNarrowerThanAPixelAcross) {
  // Under PlayCanvas' dilation (0.075 px^2) a splat of 0.15 px sigma spans
  // 2 sqrt(2 (0.0225 + 0.075)) = 0.88 px, one of 0.3 px 1.15 px: the first
  // is dropped, the second drawn as without the limit.
  RenderConventions playcanvas;
  playcanvas.dilation_px2 = 0.075;
  RenderConventions limited = playcanvas;
  limited.min_extent_px = 1;
  const GaussianModel narrow = OneSplat(32, 24, 0.15);
  const GaussianModel wider = OneSplat(32, 24, 0.3);
  EXPECT_GT(Lit(Render(narrow, AxisCamera(), playcanvas)), 0.01);
  EXPECT_EQ(Lit(Render(narrow, AxisCamera(), limited)), 0.0);
  EXPECT_EQ(Render(wider, AxisCamera(), limited).data,
            Render(wider, AxisCamera(), playcanvas).data);
  // Inria's 0.3 px^2 dilation alone makes every splat 1.55 px across.
  RenderConventions inria_dilation;
  inria_dilation.min_extent_px = 1;
  EXPECT_EQ(Render(narrow, AxisCamera(), inria_dilation).data,
            Render(narrow, AxisCamera(), RenderConventions()).data);
}

TEST(RenderConventions, FalloffsCutAndRenormaliseAt2_83Sigma) {
  // A round splat of 2 px sigma on the axis: dilated, sigma^2 = 4.3 px^2.
  // Pixels 4 and 6 px right of its centre lie at d^2 = 16 / 4.3 = 3.7
  // (inside 2.83 sigma) and 36 / 4.3 = 8.4 (outside, where Inria still draws
  // it).
  const GaussianModel splat = OneSplat(32, 24, 2.0);
  const double var = 4.3, near = 16 / var, far = 36 / var;
  auto red = [&](Falloff falloff, int x) {
    RenderConventions conventions;
    conventions.falloff = falloff;
    return Red(Render(splat, AxisCamera(), conventions), x, 24);
  };
  const double edge = std::exp(-4.0);
  EXPECT_NEAR(red(Falloff::kInria, 36), 0.25 * std::exp(-0.5 * near), 1e-5);
  EXPECT_NEAR(red(Falloff::kInria, 38), 0.25 * std::exp(-0.5 * far), 1e-5);
  ASSERT_GT(0.5 * std::exp(-0.5 * far), 1 / 255.0);  // Inria draws it
  EXPECT_NEAR(red(Falloff::kCutAt8, 36), 0.25 * std::exp(-0.5 * near), 1e-5);
  EXPECT_EQ(red(Falloff::kCutAt8, 38), 0.f);
  EXPECT_NEAR(red(Falloff::kNormalized, 36),
              0.25 * (std::exp(-0.5 * near) - edge) / (1 - edge), 1e-5);
  EXPECT_EQ(red(Falloff::kNormalized, 38), 0.f);
  // The cut sits at d^2 = 8: 6 px out, a splat of 2.063 px sigma (d^2 =
  // 7.9) is drawn, one of 2.036 px (d^2 = 8.1) is not.
  for (const auto& [sigma, inside] : {std::pair{2.063, true}, {2.036, false}}) {
    RenderConventions cut;
    cut.falloff = Falloff::kCutAt8;
    const GaussianModel edge_splat = OneSplat(32, 24, sigma);
    EXPECT_EQ(Red(Render(edge_splat, AxisCamera(), cut), 38, 24) > 0, inside)
        << sigma;
    EXPECT_GT(
        Red(Render(edge_splat, AxisCamera(), RenderConventions()), 38, 24),
        0.f);
  }
  // The centre keeps the full opacity under every falloff.
  for (Falloff falloff :
       {Falloff::kInria, Falloff::kCutAt8, Falloff::kNormalized}) {
    EXPECT_NEAR(red(falloff, 32), 0.25, 1e-5);
  }
}

TEST(RenderConventions, BlendWeightsFollowTheFalloff) {
  // White splats on black: each pixel's value is its blending weights' sum,
  // so the per-Gaussian weights add up to the image's sum under every
  // falloff, and the cut ones lose weight.
  const RenderCamera camera = RandomCamera(64, 48, 3);
  SceneSpec spec;
  spec.sh_degree = 0;
  GaussianModel model = RandomScene(camera, spec, 17);
  for (float& dc : model.sh_dc) dc = float(0.5 / kShC0);  // colour 1
  double inria_total = 0;
  for (Falloff falloff :
       {Falloff::kInria, Falloff::kCutAt8, Falloff::kNormalized}) {
    RenderOptions options;
    options.conventions.falloff = falloff;
    std::vector<double> weights(model.size(), 0.0);
    MakeCpuRasterizer()->AccumulateBlendWeights(model, camera, options,
                                                &weights);
    double total = 0;
    for (double w : weights) total += w;
    const double lit = Lit(Render(model, camera, options.conventions)) / 3;
    EXPECT_NEAR(total, lit, 1e-3 * lit) << int(falloff);
    if (falloff == Falloff::kInria) inria_total = total;
    if (falloff != Falloff::kInria) EXPECT_LT(total, inria_total);
  }
}

TEST(RenderConventions, FastForwardMatchesTheReferenceUnderEachNamedSet) {
  // Random scenes with means up to 30 px outside the frame, some splats
  // brighter than 1 and some wider than PlayCanvas' cap (17 px sigma in a
  // 64 px high frame).
  for (unsigned seed = 0; seed < 4; ++seed) {
    const RenderCamera camera = RandomCamera(80, 64, 90 + seed);
    SceneSpec spec;
    spec.count = 80;
    spec.margin = 30;
    spec.sh_degree = seed % 4;
    GaussianModel model = RandomScene(camera, spec, 100 + seed);
    for (size_t i = 0; i < model.size(); i += 5) {
      model.sh_dc[3 * i] = float((1.4 - 0.5) / kShC0);
      for (int d = 0; d < 3; ++d) model.log_scales[3 * i + d] += 1.8f;
    }
    // And a scene of splats about a pixel wide and smaller, where the
    // eigenvalue floor and the minimum size drop some.
    SceneSpec tiny_spec = spec;
    tiny_spec.min_scale = 0.0003, tiny_spec.max_scale = 0.008;
    const GaussianModel tiny = RandomScene(camera, tiny_spec, 200 + seed);
    for (const GaussianModel* scene :
         std::vector<const GaussianModel*>{&model, &tiny}) {
      std::vector<NamedRenderConventions> sets = RenderConventionsRegistry();
      for (const NamedRenderConventions& named : RenderConventionsRegistry()) {
        if (!named.conventions.composite_8bit) continue;
        // The storage rules alone, compared exactly below.
        NamedRenderConventions float_sum = named;
        float_sum.name += " without the 8-bit composite";
        float_sum.conventions.composite_8bit = false;
        sets.push_back(float_sum);
      }
      for (const NamedRenderConventions& named : sets) {
        RenderOptions options;
        options.conventions = named.conventions;
        // Grey: 0.3 x 255 is a half level in float (76.5), where two
        // rounding rules would part.
        options.background = {0.3f, 0.5f, 0.1f};
        ImageRGB image;
        MakeCpuRasterizer()->Forward(*scene, camera, options, &image, nullptr);
        const std::vector<double> reference =
            ReferenceRender(ReferenceModel::From(*scene), camera, options);
        ASSERT_EQ(image.data.size(), reference.size());
        double worst = 0;
        size_t off_a_level = 0;
        for (size_t k = 0; k < reference.size(); ++k) {
          const double diff = std::abs(double(image.data[k]) - reference[k]);
          worst = std::max(worst, diff);
          off_a_level += diff > 1e-5;
        }
        const std::string where = named.name + ", seed " +
                                  std::to_string(seed) +
                                  (scene == &tiny ? ", tiny splats" : "");
        if (named.conventions.composite_8bit) {
          // Float and double round a blend to its 8-bit level alike (halves
          // up) but where they straddle a half level: one level, rarely.
          EXPECT_LT(worst, 1.0 / 255 + 1e-5) << where;
          EXPECT_LT(off_a_level, reference.size() / 100) << where;
        } else {
          EXPECT_LT(worst, 1e-5) << where;
        }
      }
    }
    // The tiny scene loses splats under both viewers' sets: the drops are
    // compared above, not only the ellipses.
    RenderOptions plain_options;
    std::unique_ptr<RenderContext> plain_context, web_context, pc_context;
    ImageRGB scratch;
    auto visible = [&](const RenderConventions& conventions,
                       std::unique_ptr<RenderContext>* context) {
      RenderOptions options;
      options.conventions = conventions;
      options.conventions.cull_centre_outside = 0;  // drops by size only
      MakeCpuRasterizer()->Forward(tiny, camera, options, &scratch, context);
      const auto& ctx = dynamic_cast<const CpuRenderContext&>(**context);
      return std::count(ctx.visible.begin(), ctx.visible.end(), 1);
    };
    const auto all = visible(RenderConventions(), &plain_context);
    EXPECT_LT(visible(Web(), &web_context), all) << seed;
    EXPECT_LT(visible(FindRenderConventions("playcanvas", "test").conventions,
                      &pc_context),
              all)
        << seed;
    // The sets differ from each other on these scenes.
    const ImageRGB plain = Render(model, camera, RenderConventions());
    EXPECT_NE(Render(model, camera, Web()).data, plain.data) << seed;
    EXPECT_NE(Render(model, camera,
                     FindRenderConventions("playcanvas", "test").conventions)
                  .data,
              plain.data)
        << seed;
  }
}

TEST(RenderConventions, DilationAndUnclampedJacobianAsPlayCanvasHasThem) {
  // A splat of 0.5 px sigma: one pixel off its centre, its alpha is
  // 0.5 exp(-0.5 / (0.25 + dilation)).
  const GaussianModel tiny = OneSplat(32, 24, 0.5);
  RenderConventions thin;
  thin.dilation_px2 = 0.075;
  EXPECT_NEAR(Red(Render(tiny, AxisCamera(), RenderConventions()), 33, 24),
              0.25 * std::exp(-0.5 / 0.55), 1e-5);
  EXPECT_NEAR(Red(Render(tiny, AxisCamera(), thin), 33, 24),
              0.25 * std::exp(-0.5 / 0.325), 1e-5);
  // Centred at x/z = 1.3 (Inria clamps at 1.3 x 0.64): the unclamped
  // Jacobian widens its footprint in the frame; one centred in the frame
  // renders the same either way.
  RenderConventions unclamped;
  unclamped.unclamped_jacobian = true;
  const GaussianModel far = OneSplat(97, 24, 12);
  EXPECT_GT(Lit(Render(far, AxisCamera(), unclamped)),
            Lit(Render(far, AxisCamera(), RenderConventions())) + 1.0);
  const GaussianModel near = OneSplat(40, 30, 6);
  EXPECT_EQ(Render(near, AxisCamera(), unclamped).data,
            Render(near, AxisCamera(), RenderConventions()).data);
}

TEST(RenderConventions, BackwardRunsWithTheCullAndRefusesTheClampAndCap) {
  const RenderCamera camera = AxisCamera();
  GaussianModel model = OneSplat(1.15 * 64, 24, 12);
  const GaussianModel inside = OneSplat(40, 20, 5);
  model.Resize(2);
  for (int d = 0; d < 3; ++d) {
    model.means[3 + d] = inside.means[d];
    model.log_scales[3 + d] = inside.log_scales[d];
    model.sh_dc[3 + d] = inside.sh_dc[d];
  }
  for (int d = 0; d < 4; ++d) model.quats[4 + d] = inside.quats[d];
  model.opacity_logits[1] = 0;
  RenderConventions cull;
  cull.cull_centre_outside = 1.2;
  std::unique_ptr<RenderContext> context;
  const ImageRGB image = Render(model, camera, cull, &context);
  ImageRGB ones = image;
  std::fill(ones.data.begin(), ones.data.end(), 1.f);
  GaussianGradients grads;
  MakeCpuRasterizer()->Backward(model, *context, ones, &grads);
  EXPECT_EQ(grads.visible, (std::vector<uint8_t>{0, 1}));
  for (int d = 0; d < 3; ++d) {
    EXPECT_EQ(grads.means[d], 0.f);
    EXPECT_EQ(grads.sh_dc[d], 0.f);
  }
  EXPECT_NE(grads.sh_dc[3], 0.f);

  RenderConventions thin;
  thin.dilation_px2 = 0.1;
  RenderConventions floor;
  floor.eigen_gap_floor = 0.1;
  RenderConventions min_extent;
  min_extent.min_extent_px = 1;
  RenderConventions cut;
  cut.falloff = Falloff::kCutAt8;
  for (const RenderConventions& conventions :
       {Web(), FindRenderConventions("playcanvas", "test").conventions, thin,
        floor, min_extent, cut}) {
    Render(model, camera, conventions, &context);
    try {
      MakeCpuRasterizer()->Backward(model, *context, ones, &grads);
      FAIL() << "the backward pass ran";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("no backward pass"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(RenderConventions, OutOfRangeValuesAndOtherRenderersFailInOneLine) {
  const GaussianModel model = OneSplat(32, 24, 4);
  RenderConventions bad;
  bad.cull_centre_outside = -1;
  EXPECT_THROW(Render(model, AxisCamera(), bad), Error);
  bad.cull_centre_outside = NAN;
  EXPECT_THROW(Render(model, AxisCamera(), bad), Error);
  bad = RenderConventions();
  bad.extent_cap_px = -5;
  EXPECT_THROW(Render(model, AxisCamera(), bad), Error);
  bad = RenderConventions();
  bad.dilation_px2 = 0.5;
  EXPECT_THROW(Render(model, AxisCamera(), bad), Error);
  for (double extent : {-1.0, double(INFINITY), double(NAN)}) {
    bad = RenderConventions();
    bad.min_extent_px = extent;
    EXPECT_THROW(Render(model, AxisCamera(), bad), Error) << extent;
  }
  for (double floor : {-0.1, 0.2, double(NAN)}) {
    bad = RenderConventions();
    bad.eigen_gap_floor = floor;
    EXPECT_THROW(Render(model, AxisCamera(), bad), Error) << floor;
  }
  EXPECT_NO_THROW(RequireDefaultConventions(RenderConventions(), "x"));
  // Each field alone makes a set non-default, so renderers without
  // conventions (CUDA) refuse it and extract reads through them.
  std::vector<RenderConventions> single(8);
  single[0].cull_centre_outside = 1.2;
  single[1].max_sh_degree = 0;
  single[2].clamp_base_color = true;
  single[3].extent_cap_px = 1024;
  single[4].dilation_px2 = 0.075;
  single[5].unclamped_jacobian = true;
  single[6].eigen_gap_floor = 0.1;
  single[7].min_extent_px = 1;
  RenderConventions falloff;
  falloff.falloff = Falloff::kNormalized;
  single.push_back(falloff);
  single.emplace_back().base_opacity_8bit = true;
  single.emplace_back().composite_8bit = true;
  single.emplace_back().compact_work_buffer = true;
  for (size_t k = 0; k < single.size(); ++k) {
    EXPECT_FALSE(single[k].IsDefault()) << k;
    // The cull, the SH cap and the unclamped Jacobian have a backward pass.
    EXPECT_EQ(single[k].ForwardOnly(), k != 0 && k != 1 && k != 5) << k;
    EXPECT_THROW(RequireDefaultConventions(single[k], "x"), Error) << k;
  }
  try {
    RequireDefaultConventions(Web(), "the CUDA rasterizer");
    FAIL() << "non-default conventions were accepted";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos);
    EXPECT_NE(message.find("the CUDA rasterizer"), std::string::npos);
  }
  EXPECT_EQ(EffectiveShDegree(-1, 3, RenderConventions()), 3);
  EXPECT_EQ(EffectiveShDegree(2, 3, RenderConventions()), 2);
  EXPECT_EQ(EffectiveShDegree(5, 1, RenderConventions()), 1);
  EXPECT_EQ(EffectiveShDegree(-1, 3, Web()), 0);
}

}  // namespace
}  // namespace watergs
