// Tests for the training losses: SSIM against a direct 2-D reference, analytic
// gradients against central finite differences in double, edge cases.
#include "gaussian/loss.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

std::vector<double> RandomImage(int w, int h, int c, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v(size_t(w) * h * c);
  for (double& x : v) x = u(rng);
  return v;
}

// Straightforward SSIM: full 11x11 window, zero padding, one pixel at a time.
double ReferenceSsim(const std::vector<double>& x, const std::vector<double>& y,
                     int w, int h, int c) {
  double g[11], sum = 0;
  for (int k = 0; k < 11; ++k) {
    g[k] = std::exp(-(k - 5) * (k - 5) / (2 * 1.5 * 1.5));
    sum += g[k];
  }
  for (double& v : g) v /= sum;
  const double c1 = 1e-4, c2 = 9e-4;
  double total = 0;
  for (int ch = 0; ch < c; ++ch) {
    for (int py = 0; py < h; ++py) {
      for (int px = 0; px < w; ++px) {
        double mx = 0, my = 0, xx = 0, yy = 0, xy = 0;
        for (int dy = -5; dy <= 5; ++dy) {
          for (int dx = -5; dx <= 5; ++dx) {
            const int qx = px + dx, qy = py + dy;
            if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
            const double wt = g[dx + 5] * g[dy + 5];
            const double a = x[(size_t(qy) * w + qx) * c + ch];
            const double b = y[(size_t(qy) * w + qx) * c + ch];
            mx += wt * a;
            my += wt * b;
            xx += wt * a * a;
            yy += wt * b * b;
            xy += wt * a * b;
          }
        }
        const double sxx = xx - mx * mx, syy = yy - my * my, sxy = xy - mx * my;
        total += ((2 * mx * my + c1) * (2 * sxy + c2)) /
                 ((mx * mx + my * my + c1) * (sxx + syy + c2));
      }
    }
  }
  return total / (double(w) * h * c);
}

TEST(Loss, SsimMatchesDirectZeroPaddedReference) {
  for (auto [w, h] : {std::pair{17, 12}, std::pair{4, 3}, std::pair{1, 1}}) {
    const auto x = RandomImage(w, h, 3, 1);
    const auto y = RandomImage(w, h, 3, 2);
    const double fast = SsimInterleaved(x.data(), y.data(), w, h, 3,
                                        static_cast<double*>(nullptr));
    EXPECT_NEAR(fast, ReferenceSsim(x, y, w, h, 3), 1e-12) << w << "x" << h;
  }
}

TEST(Loss, SsimGradientMatchesFiniteDifferences) {
  for (auto [w, h] : {std::pair{13, 9}, std::pair{5, 7}}) {
    auto x = RandomImage(w, h, 3, 3);
    const auto y = RandomImage(w, h, 3, 4);
    std::vector<double> grad(x.size());
    SsimInterleaved(x.data(), y.data(), w, h, 3, grad.data());
    const double eps = 1e-6;
    double max_abs = 0;
    for (double gv : grad) max_abs = std::max(max_abs, std::abs(gv));
    ASSERT_GT(max_abs, 0);
    for (size_t i = 0; i < x.size(); ++i) {
      const double saved = x[i];
      x[i] = saved + eps;
      const double plus = SsimInterleaved(x.data(), y.data(), w, h, 3,
                                          static_cast<double*>(nullptr));
      x[i] = saved - eps;
      const double minus = SsimInterleaved(x.data(), y.data(), w, h, 3,
                                           static_cast<double*>(nullptr));
      x[i] = saved;
      EXPECT_NEAR(grad[i], (plus - minus) / (2 * eps), 1e-7 * max_abs + 1e-10)
          << "element " << i << " of " << w << "x" << h;
    }
  }
}

TEST(Loss, L1GradientMatchesFiniteDifferences) {
  auto x = RandomImage(6, 5, 3, 5);
  const auto y = RandomImage(6, 5, 3, 6);
  std::vector<double> grad(x.size());
  L1Interleaved(x.data(), y.data(), x.size(), grad.data());
  const double eps = 1e-7;
  for (size_t i = 0; i < x.size(); ++i) {
    const double saved = x[i];
    x[i] = saved + eps;
    const double plus = L1Interleaved(x.data(), y.data(), x.size(),
                                      static_cast<double*>(nullptr));
    x[i] = saved - eps;
    const double minus = L1Interleaved(x.data(), y.data(), x.size(),
                                       static_cast<double*>(nullptr));
    x[i] = saved;
    EXPECT_NEAR(grad[i], (plus - minus) / (2 * eps), 1e-8);
  }
}

ImageRGB ToImage(const std::vector<double>& v, int w, int h) {
  ImageRGB img(w, h);
  for (size_t i = 0; i < v.size(); ++i) img.data[i] = float(v[i]);
  return img;
}

TEST(Loss, TrainingLossCombinesTermsWithLambda) {
  const int w = 23, h = 19;
  const auto xd = RandomImage(w, h, 3, 7);
  const auto yd = RandomImage(w, h, 3, 8);
  const ImageRGB x = ToImage(xd, w, h), y = ToImage(yd, w, h);
  TrainingLoss loss(0.2);
  ImageRGB grad;
  const LossTerms terms = loss.Evaluate(x, y, &grad);
  // Double-precision terms on the same (float-rounded) inputs.
  std::vector<double> xr(xd.size()), yr(yd.size());
  for (size_t i = 0; i < xd.size(); ++i) {
    xr[i] = x.data[i];
    yr[i] = y.data[i];
  }
  std::vector<double> g_l1(xr.size()), g_ssim(xr.size());
  const double l1 = L1Interleaved(xr.data(), yr.data(), xr.size(), g_l1.data());
  const double ssim =
      SsimInterleaved(xr.data(), yr.data(), w, h, 3, g_ssim.data());
  EXPECT_NEAR(terms.l1, l1, 1e-6);
  EXPECT_NEAR(terms.ssim, ssim, 1e-5);
  EXPECT_NEAR(terms.total, 0.8 * l1 + 0.2 * (1 - ssim), 1e-5);
  ASSERT_EQ(grad.width, w);
  ASSERT_EQ(grad.height, h);
  for (size_t i = 0; i < xr.size(); ++i) {
    const double expected = 0.8 * g_l1[i] - 0.2 * g_ssim[i];
    EXPECT_NEAR(grad.data[i], expected, 1e-4 * std::abs(expected) + 1e-9);
  }
}

TEST(Loss, SsimOfIdenticalImagesIsOne) {
  const ImageRGB x = ToImage(RandomImage(31, 17, 3, 9), 31, 17);
  ImageRGB grad;
  EXPECT_NEAR(Ssim(x, x, &grad), 1.0, 1e-6);
  // SSIM is maximal at x == y, so its gradient vanishes there.
  for (float g : grad.data) EXPECT_NEAR(g, 0.f, 1e-6f);
}

TEST(Loss, ConstantImagesStayFinite) {
  for (float a : {0.f, 1.f, 0.5f}) {
    for (float b : {0.f, 1.f}) {
      ImageRGB x(12, 8), y(12, 8);
      std::fill(x.data.begin(), x.data.end(), a);
      std::fill(y.data.begin(), y.data.end(), b);
      ImageRGB grad;
      TrainingLoss loss;
      const LossTerms t = loss.Evaluate(x, y, &grad);
      EXPECT_TRUE(std::isfinite(t.total));
      EXPECT_TRUE(std::isfinite(t.ssim));
      if (a == b) {
        EXPECT_NEAR(t.ssim, 1.0, 1e-6);
      }
      for (float g : grad.data) ASSERT_TRUE(std::isfinite(g));
    }
  }
}

TEST(Loss, PsnrOfKnownError) {
  ImageRGB x(4, 4), y(4, 4);
  std::fill(x.data.begin(), x.data.end(), 0.6f);
  std::fill(y.data.begin(), y.data.end(), 0.5f);
  EXPECT_NEAR(Psnr(x, y), 20.0, 1e-4);            // MSE 0.01
  std::fill(x.data.begin(), x.data.end(), 1.5f);  // clamped to 1
  std::fill(y.data.begin(), y.data.end(), 0.9f);
  EXPECT_NEAR(Psnr(x, y), 20.0, 1e-4);
  EXPECT_TRUE(std::isinf(Psnr(y, y)));
}

TEST(Loss, MismatchedSizesAreAnError) {
  ImageRGB x(4, 4), y(4, 5);
  EXPECT_THROW(Ssim(x, y), Error);
}

}  // namespace
}  // namespace watergs
