// Parity of the CUDA rasterizer with the CPU one (the reference): forward
// images and every gradient group, on random scenes, several poses, crops,
// tile borders, a stack deeper than one shared-memory batch, clamped colour
// channels and capped alphas, an SH-degree-0 model, hard inputs, an empty
// model and a 1x1 image. Each parity test skips (saying why)
// without a usable GPU; the last test checks the error a GPU-less machine
// gives instead.
//
// Tolerances. Both sides compute the per-Gaussian math in double and blend
// in float with the same expressions (same exp polynomial), so images agree
// to float rounding: max |gpu - cpu| <= 1e-4. Gradients of the blending
// are summed in a different order (atomicAdd per warp vs per tile), so each
// group must agree within 1e-3 of the group's largest |cpu| entry; flags
// (visible) must agree exactly. A group that is zero in exact arithmetic
// (the quaternions of isotropic Gaussians: their covariance does not depend
// on the rotation) holds only rounding residue of a cancellation (2e-19
// against gradients of order 1 in the deep-stack scene), of either sign on
// either backend, so "1e-3 of its largest entry" would ask the residues to
// agree. Each group's scale is therefore floored at kNumericalZero of the
// largest entry of any parameter group of the same render: float blending
// sums carry relative errors of ~1e-7 per term, so entries a million times
// below the render's largest gradient are not resolved by either backend.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/device.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"
#include "tests/gaussian/rasterizer_test_scenes.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"
#endif

namespace watergs {
namespace {

using testing::RandomCamera;
using testing::RandomScene;
using testing::SceneSpec;

constexpr double kImageTolerance = 1e-4;
constexpr double kGradientRelTolerance = 1e-3;
// Fraction of a render's largest gradient below which a group counts as
// numerically zero (see the header).
constexpr double kNumericalZero = 1e-6;

// A forward image and the gradients of sum(weights * image).
struct Rendered {
  ImageRGB image;
  GaussianGradients grads;
};

// dL/d(image): a fixed pseudo-random pattern in [-1, 1].
ImageRGB PatternGradient(int width, int height) {
  ImageRGB grad(width, height);
  std::mt19937 rng(static_cast<unsigned>(width * 7919 + height));
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (float& v : grad.data) v = u(rng);
  return grad;
}

Rendered Render(Rasterizer& rasterizer, const GaussianModel& model,
                const RenderCamera& cam, const RenderOptions& options,
                bool compact_sh) {
  Rendered out;
  std::unique_ptr<RenderContext> context;
  rasterizer.Forward(model, cam, options, &out.image, &context);
  out.grads.compact_sh = compact_sh;
  rasterizer.Backward(model, *context,
                      PatternGradient(out.image.width, out.image.height),
                      &out.grads);
  return out;
}

size_t NonFinite(const std::vector<float>& v) {
  return static_cast<size_t>(std::count_if(
      v.begin(), v.end(), [](float x) { return !std::isfinite(x); }));
}

double MaxAbs(const std::vector<float>& v) {
  double m = 0;
  for (float x : v) m = std::max(m, std::fabs(double(x)));
  return m;
}

// Empty when |gpu - cpu| <= tolerance * max(max |cpu| over the group,
// floor) for every entry and gpu is finite; else what is wrong, on one line.
std::string GroupMismatch(const std::vector<float>& cpu,
                          const std::vector<float>& gpu, double tolerance,
                          double floor) {
  if (cpu.size() != gpu.size()) {
    return "sizes differ: cpu " + std::to_string(cpu.size()) + " gpu " +
           std::to_string(gpu.size());
  }
  if (NonFinite(gpu) > 0) {
    return std::to_string(NonFinite(gpu)) + " non-finite gpu entries";
  }
  const double scale = std::max(MaxAbs(cpu), floor);
  double worst = 0;
  size_t worst_at = 0;
  for (size_t k = 0; k < cpu.size(); ++k) {
    const double d = std::fabs(double(gpu[k]) - double(cpu[k]));
    if (d > worst) worst = d, worst_at = k;
  }
  if (worst <= tolerance * scale) return "";
  std::ostringstream out;
  out.precision(17);
  out << "entry " << worst_at << " cpu " << cpu[worst_at] << " gpu "
      << gpu[worst_at] << " differ by " << worst << " > " << tolerance << " x "
      << scale << " (largest |cpu| " << MaxAbs(cpu) << ", floor " << floor
      << ")";
  return out.str();
}

// kNumericalZero of the largest |entry| over `groups` (one render's).
double RenderFloor(std::initializer_list<const std::vector<float>*> groups) {
  double m = 0;
  for (const std::vector<float>* g : groups) m = std::max(m, MaxAbs(*g));
  return kNumericalZero * m;
}

double RenderFloor(const GaussianGradients& g) {
  return RenderFloor({&g.means, &g.log_scales, &g.quats, &g.opacity_logits,
                      &g.sh_dc, &g.sh_rest});
}

void ExpectGroupClose(const std::string& name, const std::vector<float>& cpu,
                      const std::vector<float>& gpu,
                      double tolerance = kGradientRelTolerance,
                      double floor = 0) {
  const std::string mismatch = GroupMismatch(cpu, gpu, tolerance, floor);
  EXPECT_TRUE(mismatch.empty()) << name << ": " << mismatch;
}

void ExpectImagesClose(const ImageRGB& cpu, const ImageRGB& gpu) {
  ASSERT_EQ(cpu.width, gpu.width);
  ASSERT_EQ(cpu.height, gpu.height);
  ASSERT_EQ(cpu.data.size(), gpu.data.size());
  double worst = 0;
  size_t worst_at = 0;
  for (size_t k = 0; k < cpu.data.size(); ++k) {
    const double d = std::fabs(double(gpu.data[k]) - double(cpu.data[k]));
    if (!(d <= worst)) worst = d, worst_at = k;
  }
  EXPECT_LE(worst, kImageTolerance)
      << "pixel " << worst_at / 3 % cpu.width << "," << worst_at / 3 / cpu.width
      << " channel " << worst_at % 3;
}

// Renders with both rasterizers and compares the image and every gradient.
void ExpectParity(const GaussianModel& model, const RenderCamera& cam,
                  const RenderOptions& options, bool compact_sh = false) {
  auto cpu_rasterizer = MakeCpuRasterizer();
  auto gpu_rasterizer = MakeRasterizer(Device::kCuda);
  const Rendered cpu = Render(*cpu_rasterizer, model, cam, options, compact_sh);
  const Rendered gpu = Render(*gpu_rasterizer, model, cam, options, compact_sh);
  ExpectImagesClose(cpu.image, gpu.image);
  const GaussianGradients& c = cpu.grads;
  const GaussianGradients& g = gpu.grads;
  const double floor = RenderFloor(c);
  const double tol = kGradientRelTolerance;
  ExpectGroupClose("means", c.means, g.means, tol, floor);
  ExpectGroupClose("log_scales", c.log_scales, g.log_scales, tol, floor);
  ExpectGroupClose("quats", c.quats, g.quats, tol, floor);
  ExpectGroupClose("opacity_logits", c.opacity_logits, g.opacity_logits, tol,
                   floor);
  ExpectGroupClose("sh_dc", c.sh_dc, g.sh_dc, tol, floor);
  ExpectGroupClose("sh_rest", c.sh_rest, g.sh_rest, tol, floor);
  // Per-pixel-summed intermediates, not parameters: no render floor (none
  // of them vanishes in these scenes).
  ExpectGroupClose("sh_color_grad", c.sh_color_grad, g.sh_color_grad);
  // The view direction does not depend on the blending order at all.
  ExpectGroupClose("sh_view_dir", c.sh_view_dir, g.sh_view_dir, 1e-6);
  ExpectGroupClose("mean2d_grad_norm", c.mean2d_grad_norm, g.mean2d_grad_norm);
  ExpectGroupClose("mean2d_grad_norm_ndc", c.mean2d_grad_norm_ndc,
                   g.mean2d_grad_norm_ndc);
  EXPECT_EQ(c.visible, g.visible);
  EXPECT_EQ(c.sh_active_degree, g.sh_active_degree);
  EXPECT_EQ(g.compact_sh, compact_sh);
}

// Largest |pixel - background| of an image: the scene must show something.
double Coverage(const ImageRGB& image, const RenderOptions& options) {
  double m = 0;
  for (size_t k = 0; k < image.data.size(); ++k) {
    m = std::max(m,
                 std::fabs(double(image.data[k]) - options.background[k % 3]));
  }
  return m;
}

// Places Gaussian i at camera-frame point (x, y, z).
void PlaceAt(const RenderCamera& cam, GaussianModel* m, size_t i, double x,
             double y, double z) {
  const Eigen::Vector3d w =
      cam.R.transpose() * (Eigen::Vector3d(x, y, z) - cam.t);
  for (int k = 0; k < 3; ++k) m->means[3 * i + k] = static_cast<float>(w[k]);
}

TEST(CudaRasterizer, ParityOnRandomScenesAndPoses) {
  WATERGS_REQUIRE_CUDA();
  RenderOptions options;
  options.background = {0.1f, 0.3f, 0.6f};
  for (unsigned pose = 0; pose < 4; ++pose) {
    SCOPED_TRACE("pose " + std::to_string(pose));
    const RenderCamera cam = RandomCamera(64, 48, 100 + pose);
    SceneSpec spec;
    spec.count = 60;
    const GaussianModel model = RandomScene(cam, spec, 200 + pose);
    auto gpu = MakeRasterizer(Device::kCuda);
    ImageRGB image;
    gpu->Forward(model, cam, options, &image, nullptr);
    EXPECT_GT(Coverage(image, options), 0.1);
    ExpectParity(model, cam, options);
  }
}

TEST(CudaRasterizer, ParityAtLowerActiveShDegrees) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(48, 40, 7);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 8);
  for (int degree = 0; degree <= 3; ++degree) {
    SCOPED_TRACE("active SH degree " + std::to_string(degree));
    RenderOptions options;
    options.active_sh_degree = degree;
    ExpectParity(model, cam, options);
  }
}

TEST(CudaRasterizer, ShDegreeZeroModelMatchesCpu) {
  // No higher SH coefficients at all: sh_rest is empty on the host, so the
  // device model's sh_rest pointer is null and must never be read.
  const RenderCamera cam = RandomCamera(48, 40, 15);
  SceneSpec spec;
  spec.sh_degree = 0;
  const GaussianModel model = RandomScene(cam, spec, 16);
  ASSERT_TRUE(model.sh_rest.empty());
  WATERGS_REQUIRE_CUDA();
  for (bool compact : {false, true}) {
    SCOPED_TRACE(compact ? "compact SH" : "dense SH");
    ExpectParity(model, cam, RenderOptions(), compact);
  }
}

// Whether the 0.99 alpha cap binds at one of the four pixel centres of the
// frame around splat s's mean.
bool CapBinds(const Splat& s, const RenderCamera& cam) {
  const double x0 = std::floor(s.mean_x - 0.5) + 0.5;
  const double y0 = std::floor(s.mean_y - 0.5) + 0.5;
  for (double x : {x0, x0 + 1}) {
    for (double y : {y0, y0 + 1}) {
      if (x < 0 || y < 0 || x > cam.width || y > cam.height) continue;
      const double dx = x - s.mean_x, dy = y - s.mean_y;
      const double power = -0.5 * (s.conic_a * dx * dx + s.conic_c * dy * dy) -
                           s.conic_b * dx * dy;
      if (s.opacity * std::exp(power) > kMaxAlpha) return true;
    }
  }
  return false;
}

TEST(CudaRasterizer, ClampedColoursAndCappedAlphaMatchCpu) {
  // Every third Gaussian has a negative green (clamped at 0: no colour
  // gradient there), every third an opacity above the 0.99 cap (zero slope
  // where it binds): the two places where the backward is not the plain
  // formula.
  const RenderCamera cam = RandomCamera(64, 48, 17);
  SceneSpec spec;
  spec.count = 60;
  GaussianModel model = RandomScene(cam, spec, 18);
  for (size_t i = 0; i < model.size(); ++i) {
    if (i % 3 == 0) model.sh_dc[3 * i + 1] = -6.f;
    if (i % 3 != 1) continue;
    // Opacity 0.9975 and the mean on a pixel centre, where G is ~1.
    model.opacity_logits[i] = 6.f;
    const double px = 5.5 + 3.0 * double(i % 19), py = 4.5 + 2.0 * (i % 20);
    const double z = 2.5 + 0.05 * double(i);
    PlaceAt(cam, &model, i, (px - cam.cx) / cam.fx * z,
            (py - cam.cy) / cam.fy * z, z);
  }
  // The scene does what it is for (checked on the CPU, so also without a
  // GPU): some rendered splats have a clamped channel, some a capped alpha.
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  MakeCpuRasterizer()->Forward(model, cam, RenderOptions(), &image, &context);
  const auto& cpu_context = dynamic_cast<const CpuRenderContext&>(*context);
  EXPECT_GT(std::count_if(cpu_context.color_clamped.begin(),
                          cpu_context.color_clamped.end(),
                          [](uint8_t bits) { return bits & 2u; }),
            3);
  EXPECT_GT(std::count_if(cpu_context.splats.begin(), cpu_context.splats.end(),
                          [&](const Splat& s) { return CapBinds(s, cam); }),
            3);
  WATERGS_REQUIRE_CUDA();
  RenderOptions options;
  options.background = {0.3f, 0.6f, 0.2f};
  for (bool compact : {false, true}) {
    SCOPED_TRACE(compact ? "compact SH" : "dense SH");
    ExpectParity(model, cam, options, compact);
  }
}

TEST(CudaRasterizer, CompactShGradientsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(64, 48, 9);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 10);
  RenderOptions options;
  options.active_sh_degree = 2;
  ExpectParity(model, cam, options, /*compact_sh=*/true);
}

TEST(CudaRasterizer, CropRectsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(80, 56, 11);
  SceneSpec spec;
  spec.count = 80;
  const GaussianModel model = RandomScene(cam, spec, 12);
  // Unaligned, tile-aligned, one row, and the last partial tile.
  const PixelRect rects[] = {
      {5, 7, 37, 20}, {16, 16, 32, 32}, {0, 30, 80, 1}, {64, 48, 16, 8}};
  for (const PixelRect& rect : rects) {
    SCOPED_TRACE("rect " + std::to_string(rect.x0) + "," +
                 std::to_string(rect.y0) + " " + std::to_string(rect.width) +
                 "x" + std::to_string(rect.height));
    RenderOptions options;
    options.rect = rect;
    options.background = {0.5f, 0.25f, 0.f};
    ExpectParity(model, cam, options);
  }
}

TEST(CudaRasterizer, TileBorderGaussiansMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(64, 48, 13);
  SceneSpec spec;
  spec.count = 24;
  spec.min_scale = 0.005, spec.max_scale = 0.05;
  GaussianModel model = RandomScene(cam, spec, 14);
  // Means on tile corners and edges (pixel coordinates multiple of 16), at
  // depths where the splats are a few pixels wide.
  for (size_t i = 0; i < model.size(); ++i) {
    const double px = 16.0 * (1 + i % 3) + (i % 2 ? 0.0 : 0.5);
    const double py = 16.0 * (1 + i / 3 % 2) + (i % 4 < 2 ? 0.0 : -0.5);
    const double z = 2.0 + 0.1 * double(i);
    PlaceAt(cam, &model, i, (px - cam.cx) / cam.fx * z,
            (py - cam.cy) / cam.fy * z, z);
  }
  ExpectParity(model, cam, RenderOptions());
  RenderOptions crop;
  crop.rect = {16, 16, 16, 16};
  ExpectParity(model, cam, crop);
}

// 1500 faint isotropic Gaussians on one 16 x 16 image: pixels blend splats
// from several 256-splat shared-memory batches, forward and backward.
GaussianModel DeepTileStack(RenderCamera* cam) {
  cam->width = 16, cam->height = 16;
  cam->fx = cam->fy = 20, cam->cx = cam->cy = 8;
  GaussianModel model;
  model.sh_degree = 1;
  const size_t n = 1500;
  model.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    model.means[3 * i] = 0.05f * std::sin(float(i));
    model.means[3 * i + 1] = 0.05f * std::cos(float(i));
    model.means[3 * i + 2] = 1.f + 2.f * float(i) / n;
    for (int k = 0; k < 3; ++k) model.log_scales[3 * i + k] = -3;
    model.quats[4 * i] = 1;
    model.opacity_logits[i] = i % 2 ? -4.f : -6.f;
    model.sh_dc[3 * i] = 1;
    model.sh_rest[i * model.sh_rest_stride() + 3 * (i % 3)] = 0.2f;
  }
  return model;
}

TEST(CudaRasterizer, DeepTileStackMatchesCpu) {
  RenderCamera cam;
  const GaussianModel model = DeepTileStack(&cam);
  // The scene does what it is for (checked on the CPU, so also without a
  // GPU): some pixel's last contributor lies beyond the second batch.
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  MakeCpuRasterizer()->Forward(model, cam, RenderOptions(), &image, &context);
  const auto& cpu_context = dynamic_cast<const CpuRenderContext&>(*context);
  const std::vector<uint32_t>& n_contrib = cpu_context.blend.n_contrib;
  EXPECT_GT(*std::max_element(n_contrib.begin(), n_contrib.end()), 512u);
  WATERGS_REQUIRE_CUDA();
  ExpectParity(model, cam, RenderOptions());
}

// The comparison's floor, without a GPU. The deep-stack scene's Gaussians
// are isotropic, so its quaternion gradients vanish in exact arithmetic:
// on the CPU they are residue far below the render's floor while the other
// groups are not. The first GPU run (H200, 2026-11-26) read entry 198 as
// -1.08e-19 where the CPU had 2.17e-19: a residue of the other sign, which
// the floor accepts; a real error of 1e-3 of the render's scale in a
// near-zero group, or of a group's own scale, is still refused.
TEST(RasterizerParityTolerance, NearZeroGroupsAreFlooredAtTheRenderScale) {
  RenderCamera cam;
  const GaussianModel model = DeepTileStack(&cam);
  const Rendered cpu =
      Render(*MakeCpuRasterizer(), model, cam, RenderOptions(), false);
  const GaussianGradients& c = cpu.grads;
  const double floor = RenderFloor(c);
  ASSERT_GT(floor, 0);
  EXPECT_LT(MaxAbs(c.quats), 1e-6 * floor) << "quaternions not ~0";
  for (const auto* group :
       {&c.means, &c.log_scales, &c.opacity_logits, &c.sh_dc}) {
    EXPECT_GT(MaxAbs(*group), floor);
  }
  // The logged residues: refused without the floor, accepted with it.
  std::vector<float> gpu_quats = c.quats;
  const size_t at = 198;
  ASSERT_LT(at, gpu_quats.size());
  gpu_quats[at] = -2.f * std::fabs(c.quats[at]) - 1e-19f;
  EXPECT_NE(GroupMismatch(c.quats, gpu_quats, kGradientRelTolerance, 0), "");
  EXPECT_EQ(GroupMismatch(c.quats, gpu_quats, kGradientRelTolerance, floor),
            "");
  // A near-zero group the GPU gets wrong by more than 1e-3 of the floor.
  gpu_quats[at] = float(2e-3 * floor);
  EXPECT_NE(GroupMismatch(c.quats, gpu_quats, kGradientRelTolerance, floor),
            "");
  // A non-zero group keeps its own relative tolerance.
  std::vector<float> gpu_means = c.means;
  size_t big = 0;
  for (size_t k = 0; k < gpu_means.size(); ++k) {
    if (std::fabs(c.means[k]) > std::fabs(c.means[big])) big = k;
  }
  gpu_means[big] *= 1.01f;
  EXPECT_NE(GroupMismatch(c.means, gpu_means, kGradientRelTolerance, floor),
            "");
  gpu_means[big] = c.means[big] * (1.f + 5e-4f);
  EXPECT_EQ(GroupMismatch(c.means, gpu_means, kGradientRelTolerance, floor),
            "");
}

TEST(CudaRasterizer, HardCasesStayFiniteAndMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(64, 48, 1);
  GaussianModel m = RandomScene(cam, SceneSpec(), 2);
  const float inf = std::numeric_limits<float>::infinity();
  const float denormal = std::numeric_limits<float>::denorm_min();
  size_t i = 0;
  // Behind the camera, on / just beyond the near plane, at the centre.
  PlaceAt(cam, &m, i++, 0.1, 0.1, -1.0);
  PlaceAt(cam, &m, i++, 0.0, 0.0, cam.near_plane);
  PlaceAt(cam, &m, i++, 0.001, 0.0, cam.near_plane * 1.0001);
  PlaceAt(cam, &m, i++, 0.0, 0.0, 0.0);
  PlaceAt(cam, &m, i++, 40.0, -30.0, 2.0);
  // Zero, denormal and huge scales; a needle (near-singular covariance).
  for (float ls : {-inf, std::log(denormal), -80.f, 30.f, 88.f, inf}) {
    for (int k = 0; k < 3; ++k) m.log_scales[3 * i + k] = ls;
    ++i;
  }
  m.log_scales[3 * i] = 5, m.log_scales[3 * i + 1] = -40;
  m.log_scales[3 * i + 2] = -40;
  ++i;
  // Zero-norm and denormal quaternions; opacity logits +-60.
  for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = 0;
  ++i;
  for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = denormal;
  ++i;
  m.opacity_logits[i++] = 60;
  m.opacity_logits[i++] = -60;
  ASSERT_LE(i, m.size());
  for (unsigned pose = 0; pose < 2; ++pose) {
    const RenderCamera view = pose == 0 ? cam : RandomCamera(64, 48, 20);
    auto gpu = MakeRasterizer(Device::kCuda);
    const Rendered r = Render(*gpu, m, view, RenderOptions(), false);
    EXPECT_EQ(NonFinite(r.image.data), 0u);
    for (const std::vector<float>* v :
         {&r.grads.means, &r.grads.log_scales, &r.grads.quats,
          &r.grads.opacity_logits, &r.grads.sh_dc, &r.grads.sh_rest,
          &r.grads.mean2d_grad_norm, &r.grads.mean2d_grad_norm_ndc}) {
      EXPECT_EQ(NonFinite(*v), 0u);
    }
    ExpectParity(m, view, RenderOptions());
  }
}

TEST(CudaRasterizer, EmptyModelRendersBackground) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(20, 10, 5);
  GaussianModel m;
  m.sh_degree = 2;
  RenderOptions options;
  options.background = {0.25f, 0.5f, 0.75f};
  auto gpu = MakeRasterizer(Device::kCuda);
  const Rendered r = Render(*gpu, m, cam, options, false);
  ASSERT_EQ(r.image.data.size(), 600u);
  for (int k = 0; k < 600; ++k) {
    EXPECT_EQ(r.image.data[k], options.background[k % 3]);
  }
  EXPECT_TRUE(r.grads.means.empty());
  EXPECT_TRUE(r.grads.visible.empty());
}

TEST(CudaRasterizer, OnePixelImageMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  RenderCamera cam;
  cam.width = cam.height = 1;
  cam.fx = cam.fy = 1, cam.cx = cam.cy = 0.5;
  SceneSpec spec;
  spec.count = 10;
  spec.margin = 0;
  ExpectParity(RandomScene(cam, spec, 6), cam, RenderOptions());
}

TEST(CudaRasterizer, ReusedBuffersAndLiveContextsStayCorrect) {
  WATERGS_REQUIRE_CUDA();
  // One rasterizer, models of changing size, and a context kept alive while
  // another view renders: pooled device buffers must not leak between them.
  auto gpu = MakeRasterizer(Device::kCuda);
  auto cpu = MakeCpuRasterizer();
  const RenderCamera cam_a = RandomCamera(64, 48, 30);
  const RenderCamera cam_b = RandomCamera(48, 32, 31);
  SceneSpec spec;
  for (int count : {50, 20, 90}) {
    spec.count = count;
    const GaussianModel model = RandomScene(cam_a, spec, 40 + count);
    std::unique_ptr<RenderContext> ctx_a, ctx_b, cpu_ctx;
    ImageRGB image_a, image_b, cpu_image;
    gpu->Forward(model, cam_a, RenderOptions(), &image_a, &ctx_a);
    gpu->Forward(model, cam_b, RenderOptions(), &image_b, &ctx_b);
    ImageRGB image_c;
    gpu->Forward(model, cam_b, RenderOptions(), &image_c, nullptr);
    GaussianGradients grads_a, cpu_grads;
    gpu->Backward(model, *ctx_a, PatternGradient(64, 48), &grads_a);
    cpu->Forward(model, cam_a, RenderOptions(), &cpu_image, &cpu_ctx);
    cpu->Backward(model, *cpu_ctx, PatternGradient(64, 48), &cpu_grads);
    ExpectImagesClose(cpu_image, image_a);
    EXPECT_EQ(image_b.data, image_c.data);
    ExpectGroupClose("means", cpu_grads.means, grads_a.means);
    ExpectGroupClose("sh_rest", cpu_grads.sh_rest, grads_a.sh_rest);
    EXPECT_EQ(cpu_grads.visible, grads_a.visible);
    // A second backward of the same context starts from zeroed atomics.
    GaussianGradients again;
    gpu->Backward(model, *ctx_a, PatternGradient(64, 48), &again);
    ExpectGroupClose("means, second backward", cpu_grads.means, again.means);
    ExpectGroupClose("opacity_logits, second backward",
                     cpu_grads.opacity_logits, again.opacity_logits);
  }
}

TEST(CudaRasterizer, BadRectAndCameraGiveErrors) {
  WATERGS_REQUIRE_CUDA();
  auto gpu = MakeRasterizer(Device::kCuda);
  const RenderCamera cam = RandomCamera(32, 32, 3);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 4);
  ImageRGB image;
  RenderOptions outside;
  outside.rect = {20, 0, 16, 8};
  EXPECT_THROW(gpu->Forward(model, cam, outside, &image, nullptr), Error);
  RenderCamera empty = cam;
  empty.width = 0;
  EXPECT_THROW(gpu->Forward(model, empty, RenderOptions(), &image, nullptr),
               Error);
  GaussianModel broken = model;
  broken.sh_rest.pop_back();
  EXPECT_THROW(gpu->Forward(broken, cam, RenderOptions(), &image, nullptr),
               Error);
}

#ifdef WATERGS_WITH_CUDA
// The device entry points run the same kernels as the host ones: the image
// is bit-identical, gradients agree up to the atomicAdd order.
TEST(CudaRasterizer, DeviceEntryPointsMatchHostOnes) {
  WATERGS_REQUIRE_CUDA();
  const RenderCamera cam = RandomCamera(64, 48, 50);
  const GaussianModel model = RandomScene(cam, SceneSpec(), 51);
  RenderOptions options;
  options.rect = {3, 5, 50, 30};
  options.active_sh_degree = 2;
  options.background = {0.2f, 0.4f, 0.6f};
  DeviceBuffer<float> means, log_scales, quats, logits, sh_dc, sh_rest;
  means.Upload(model.means), log_scales.Upload(model.log_scales);
  quats.Upload(model.quats), logits.Upload(model.opacity_logits);
  sh_dc.Upload(model.sh_dc), sh_rest.Upload(model.sh_rest);
  CudaModelArrays arrays;
  arrays.means = means.data(), arrays.log_scales = log_scales.data();
  arrays.quats = quats.data(), arrays.opacity_logits = logits.data();
  arrays.sh_dc = sh_dc.data(), arrays.sh_rest = sh_rest.data();
  arrays.sh_degree = model.sh_degree, arrays.count = model.size();
  const size_t n = model.size(), pixels = 50 * 30;
  for (bool compact : {false, true}) {
    SCOPED_TRACE(compact ? "compact SH" : "dense SH");
    CudaRasterizer rasterizer;
    const Rendered host = Render(rasterizer, model, cam, options, compact);
    DeviceBuffer<float> image(3 * pixels), grad_image;
    std::unique_ptr<RenderContext> context;
    rasterizer.ForwardDevice(arrays, cam, options, image.data(), &context);
    std::vector<float> device_image;
    image.Download(&device_image);
    EXPECT_EQ(device_image, host.image.data);
    grad_image.Upload(PatternGradient(50, 30).data);
    DeviceBuffer<float> g_means(3 * n), g_scales(3 * n), g_quats(4 * n),
        g_logits(n), g_dc(3 * n), g_rest(n * model.sh_rest_stride()),
        g_color(3 * n), g_dir(3 * n), g_norm(n), g_norm_ndc(n);
    DeviceBuffer<uint8_t> g_visible(n);
    CudaGradientArrays out;
    out.means = g_means.data(), out.log_scales = g_scales.data();
    out.quats = g_quats.data(), out.opacity_logits = g_logits.data();
    out.compact_sh = compact;
    out.sh_dc = g_dc.data(), out.sh_rest = g_rest.data();
    out.sh_color_grad = g_color.data(), out.sh_view_dir = g_dir.data();
    out.mean2d_grad_norm = g_norm.data();
    out.mean2d_grad_norm_ndc = g_norm_ndc.data();
    out.visible = g_visible.data();
    rasterizer.BackwardDevice(*context, grad_image.data(), out);
    auto download = [](const DeviceBuffer<float>& b) {
      std::vector<float> v;
      b.Download(&v);
      return v;
    };
    const GaussianGradients& h = host.grads;
    ExpectGroupClose("means", h.means, download(g_means));
    ExpectGroupClose("log_scales", h.log_scales, download(g_scales));
    ExpectGroupClose("quats", h.quats, download(g_quats));
    ExpectGroupClose("opacity_logits", h.opacity_logits, download(g_logits));
    if (compact) {
      ExpectGroupClose("sh_color_grad", h.sh_color_grad, download(g_color));
      ExpectGroupClose("sh_view_dir", h.sh_view_dir, download(g_dir), 0);
    } else {
      ExpectGroupClose("sh_dc", h.sh_dc, download(g_dc));
      ExpectGroupClose("sh_rest", h.sh_rest, download(g_rest));
    }
    ExpectGroupClose("mean2d_grad_norm", h.mean2d_grad_norm, download(g_norm));
    ExpectGroupClose("mean2d_grad_norm_ndc", h.mean2d_grad_norm_ndc,
                     download(g_norm_ndc));
    std::vector<uint8_t> visible;
    g_visible.Download(&visible);
    EXPECT_EQ(visible, h.visible);
  }
}
#endif  // WATERGS_WITH_CUDA

// Runs everywhere: without a usable GPU, asking for the CUDA rasterizer is a
// one-line Error, not a crash.
TEST(CudaRasterizer, WithoutGpuMakeRasterizerGivesOneLineError) {
  std::string why;
  if (CudaAvailable(&why)) GTEST_SKIP() << "a GPU is visible";
  try {
    MakeRasterizer(Device::kCuda);
    FAIL() << "MakeRasterizer(kCuda) succeeded without a GPU";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_FALSE(message.empty());
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_NE(message.find("cuda"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace watergs
