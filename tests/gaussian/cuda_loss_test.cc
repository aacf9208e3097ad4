// Parity tests of the CUDA training loss (gaussian/cuda/cuda_loss.h) against
// the CPU reference (gaussian/loss.h, itself checked against a direct SSIM
// and finite differences in loss_test.cc): values and image gradients on
// random images of odd sizes down to 1x1. They run when a GPU is visible.
//
// Tolerances: the kernels repeat loss.cc's float operations in its order;
// they differ from the CPU only where GCC fuses a multiply-add (one float
// rounding, ~6e-8 relative, amplified where SSIM's adjoint terms cancel)
// and in the order of the double sums (~1e-15). The bounds: 1e-6 absolute on
// means of values in [-1, 1], and 1e-5 of the largest gradient magnitude per
// gradient value; a wrong tap, border or formula is off by far more.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "gaussian/image.h"
#include "gaussian/loss.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_loss.h"
#endif

namespace watergs {
namespace {

#ifdef WATERGS_WITH_CUDA

constexpr double kMeanTolerance = 1e-6;
constexpr double kGradRelativeTolerance = 1e-5;

ImageRGB RandomImage(int w, int h, uint32_t seed) {
  ImageRGB image(w, h);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (float& v : image.data) v = u(rng);
  return image;
}

// `base` plus small noise: the regime training sees (SSIM near 1).
ImageRGB Perturbed(const ImageRGB& base, float sigma, uint32_t seed) {
  ImageRGB image = base;
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, sigma);
  for (float& v : image.data) v += noise(rng);
  return image;
}

void ExpectGradientsMatch(const ImageRGB& cpu, const ImageRGB& cuda,
                          const char* what) {
  ASSERT_EQ(cpu.width, cuda.width);
  ASSERT_EQ(cpu.height, cuda.height);
  ASSERT_EQ(cpu.data.size(), cuda.data.size());
  float scale = 0;
  for (float g : cpu.data) scale = std::max(scale, std::abs(g));
  const double tolerance = kGradRelativeTolerance * scale;
  size_t bad = 0;
  for (size_t j = 0; j < cpu.data.size(); ++j) {
    if (!(std::abs(double(cpu.data[j]) - cuda.data[j]) <= tolerance)) {
      if (++bad <= 5) {
        ADD_FAILURE() << what << " gradient " << j << ": cpu " << cpu.data[j]
                      << " cuda " << cuda.data[j] << " (tolerance " << tolerance
                      << ")";
      }
    }
  }
  EXPECT_EQ(bad, 0u) << what << " " << cpu.width << "x" << cpu.height;
}

struct Size {
  int w, h;
};
// 1x1 and thin images make every window border-clipped; 37x29 is odd in
// both directions; 70x41 has interior pixels with full windows.
constexpr Size kSizes[] = {{1, 1}, {1, 7}, {9, 1}, {13, 5}, {37, 29}, {70, 41}};

TEST(CudaLoss, TrainingLossAndGradientMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  for (const Size& s : kSizes) {
    const ImageRGB truth = RandomImage(s.w, s.h, 1 + s.w);
    for (const ImageRGB& rendered :
         {RandomImage(s.w, s.h, 100 + s.h), Perturbed(truth, 0.05f, 7)}) {
      TrainingLoss cpu(0.2);
      CudaTrainingLoss cuda(0.2);
      ImageRGB grad_cpu, grad_cuda;
      const LossTerms a = cpu.Evaluate(rendered, truth, &grad_cpu);
      const LossTerms b = cuda.Evaluate(rendered, truth, &grad_cuda);
      EXPECT_NEAR(a.l1, b.l1, kMeanTolerance) << s.w << "x" << s.h;
      EXPECT_NEAR(a.ssim, b.ssim, kMeanTolerance) << s.w << "x" << s.h;
      EXPECT_NEAR(a.total, b.total, kMeanTolerance) << s.w << "x" << s.h;
      ExpectGradientsMatch(grad_cpu, grad_cuda, "training loss");
      // Without a gradient the same terms come back.
      const LossTerms c = cuda.Evaluate(rendered, truth, nullptr);
      EXPECT_EQ(b.l1, c.l1);
      EXPECT_EQ(b.ssim, c.ssim);
    }
  }
}

TEST(CudaLoss, SsimAndL1MatchCpu) {
  WATERGS_REQUIRE_CUDA();
  for (const Size& s : kSizes) {
    const ImageRGB x = RandomImage(s.w, s.h, 3 + s.w);
    const ImageRGB y = Perturbed(x, 0.1f, 4);
    ImageRGB g_cpu, g_cuda;
    EXPECT_NEAR(Ssim(x, y, &g_cpu), CudaSsim(x, y, &g_cuda), kMeanTolerance);
    ExpectGradientsMatch(g_cpu, g_cuda, "ssim");
    EXPECT_NEAR(L1(x, y, &g_cpu), CudaL1(x, y, &g_cuda), kMeanTolerance);
    // L1's gradient is +-1/count or 0 per value: exactly representable.
    EXPECT_EQ(g_cpu.data, g_cuda.data);
  }
  // Identical images: SSIM 1 with zero gradient (up to float rounding of
  // terms as large as the adjoint bound 1 / (count C2)), L1 0 with sign(0) =
  // 0.
  const ImageRGB x = RandomImage(21, 17, 5);
  ImageRGB g;
  EXPECT_NEAR(CudaSsim(x, x, &g), 1.0, kMeanTolerance);
  const double adjoint_bound = 1.0 / (double(x.data.size()) * 0.03 * 0.03);
  for (float v : g.data) EXPECT_NEAR(v, 0.f, 1e-5 * adjoint_bound);
  EXPECT_EQ(CudaL1(x, x, &g), 0.0);
  for (float v : g.data) EXPECT_EQ(v, 0.f);
  // Constant images stay finite (the C1, C2 terms keep the ratio bounded).
  ImageRGB black(8, 8), white(8, 8);
  std::fill(white.data.begin(), white.data.end(), 1.f);
  const double ssim = CudaSsim(black, white, &g);
  EXPECT_TRUE(std::isfinite(ssim));
  EXPECT_NEAR(ssim, Ssim(black, white), kMeanTolerance);
  for (float v : g.data) EXPECT_TRUE(std::isfinite(v));
}

TEST(CudaLoss, DeviceEntryPointIsReproducible) {
  WATERGS_REQUIRE_CUDA();
  const ImageRGB truth = RandomImage(129, 67, 8);
  const ImageRGB rendered = Perturbed(truth, 0.03f, 9);
  DeviceBuffer<float> r, t, g1, g2;
  r.Upload(rendered.data);
  t.Upload(truth.data);
  g1.Resize(rendered.data.size());
  g2.Resize(rendered.data.size());
  CudaTrainingLoss loss(0.2);
  const LossTerms a = loss.EvaluateDevice(r.data(), t.data(), rendered.width,
                                          rendered.height, g1.data());
  const LossTerms b = loss.EvaluateDevice(r.data(), t.data(), rendered.width,
                                          rendered.height, g2.data());
  // Fixed reduction order: bit-identical sums and gradients.
  EXPECT_EQ(a.total, b.total);
  EXPECT_EQ(a.ssim, b.ssim);
  std::vector<float> h1, h2;
  g1.Download(&h1);
  g2.Download(&h2);
  EXPECT_EQ(h1, h2);
  EXPECT_NEAR(a.total,
              TrainingLoss(0.2).Evaluate(rendered, truth, nullptr).total,
              kMeanTolerance);
}

// The embedder's MSE term on the device, against its formula in double:
// total = w mean (x - y)^2, l1 = mean |x - y|, grad = 2 w (x - y) / n.
TEST(CudaLoss, MseMatchesItsFormulaInDouble) {
  WATERGS_REQUIRE_CUDA();
  for (const Size& size : kSizes) {
    const ImageRGB truth = RandomImage(size.w, size.h, 12);
    const ImageRGB rendered = Perturbed(truth, 0.05f, 13);
    const size_t n = truth.data.size();
    const double weight = 50;
    double sq = 0, abs = 0;
    ImageRGB expected(size.w, size.h);
    for (size_t j = 0; j < n; ++j) {
      const double d = double(rendered.data[j]) - truth.data[j];
      sq += d * d;
      abs += std::abs(d);
      expected.data[j] = float(2 * weight * d / double(n));
    }
    DeviceBuffer<float> r, t, g;
    r.Upload(rendered.data);
    t.Upload(truth.data);
    g.Resize(n);
    CudaTrainingLoss loss;
    const LossTerms terms =
        loss.MseDevice(r.data(), t.data(), n, weight, g.data());
    EXPECT_NEAR(terms.total, weight * sq / double(n), kMeanTolerance * weight);
    EXPECT_NEAR(terms.l1, abs / double(n), kMeanTolerance);
    ImageRGB got(size.w, size.h);
    g.Download(&got.data);
    ExpectGradientsMatch(expected, got, "mse");
  }
}

TEST(CudaLoss, MismatchedSizesAreAnError) {
  WATERGS_REQUIRE_CUDA();
  CudaTrainingLoss loss;
  ImageRGB grad;
  EXPECT_THROW(loss.Evaluate(ImageRGB(4, 3), ImageRGB(3, 4), &grad), Error);
  EXPECT_THROW(CudaSsim(ImageRGB(2, 2), ImageRGB(2, 3)), Error);
}

#else

TEST(CudaLoss, SkippedWithoutCudaBackend) { WATERGS_REQUIRE_CUDA(); }

#endif

}  // namespace
}  // namespace watergs
