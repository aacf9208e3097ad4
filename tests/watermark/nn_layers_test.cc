// Checks every NN layer against an independent double-precision reference:
// forward values, and backward (input and weight gradients) against central
// finite differences of that reference.
#include "watermark/nn_layers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <random>

namespace watergs {
namespace {

std::vector<double> ToDouble(const std::vector<float>& v) {
  return std::vector<double>(v.begin(), v.end());
}

Tensor RandomTensor(int n, int c, int h, int w, std::mt19937* rng,
                    float scale = 1.f) {
  Tensor t(n, c, h, w);
  std::normal_distribution<float> dist(0.f, scale);
  for (float& v : t.data) v = dist(*rng);
  return t;
}

// Central difference of f at x (in place), step 1e-6, all in double.
std::vector<double> NumericGradient(std::vector<double>* x,
                                    const std::function<double()>& f) {
  std::vector<double> grad(x->size());
  for (size_t i = 0; i < x->size(); ++i) {
    const double saved = (*x)[i];
    const double h = 1e-6 * std::max(1.0, std::abs(saved));
    (*x)[i] = saved + h;
    const double plus = f();
    (*x)[i] = saved - h;
    const double minus = f();
    (*x)[i] = saved;
    grad[i] = (plus - minus) / (2 * h);
  }
  return grad;
}

// Analytic (float) and numeric gradients agree to 1e-3 of the larger norm.
void ExpectClose(const std::vector<float>& analytic,
                 const std::vector<double>& numeric, const char* what) {
  ASSERT_EQ(analytic.size(), numeric.size()) << what;
  double scale = 1e-6;
  for (double v : numeric) scale = std::max(scale, std::abs(v));
  for (size_t i = 0; i < numeric.size(); ++i)
    EXPECT_NEAR(analytic[i], numeric[i], 1e-3 * scale)
        << what << " [" << i << "]";
}

// Reference convolution in double: stride 1, zero padding k/2.
std::vector<double> RefConv(const std::vector<double>& x, int n, int cin, int h,
                            int w, const std::vector<double>& weight,
                            const std::vector<double>& bias, int cout, int k) {
  std::vector<double> y(size_t(n) * cout * h * w);
  const int pad = k / 2;
  for (int b = 0; b < n; ++b)
    for (int o = 0; o < cout; ++o)
      for (int yy = 0; yy < h; ++yy)
        for (int xx = 0; xx < w; ++xx) {
          double sum = bias[o];
          for (int i = 0; i < cin; ++i)
            for (int ky = 0; ky < k; ++ky)
              for (int kx = 0; kx < k; ++kx) {
                const int sy = yy + ky - pad, sx = xx + kx - pad;
                if (sy < 0 || sy >= h || sx < 0 || sx >= w) continue;
                sum += weight[((size_t(o) * cin + i) * k + ky) * k + kx] *
                       x[((size_t(b) * cin + i) * h + sy) * w + sx];
              }
          y[((size_t(b) * cout + o) * h + yy) * w + xx] = sum;
        }
  return y;
}

double Dot(const std::vector<double>& a, const std::vector<float>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

void CheckConv(int kernel, int h = 5, int w = 6) {
  std::mt19937 rng(3);
  const int n = 2, cin = 3, cout = 4;
  Conv2d conv("c", cin, cout, kernel, &rng);
  Tensor x = RandomTensor(n, cin, h, w, &rng);
  Tensor dy = RandomTensor(n, cout, h, w, &rng);
  Tensor y, dx;
  conv.Forward(x, &y);
  std::vector<double> xd = ToDouble(x.data), wd = ToDouble(conv.weight.value),
                      bd = ToDouble(conv.bias.value);
  const std::vector<double> ref =
      RefConv(xd, n, cin, h, w, wd, bd, cout, kernel);
  for (size_t i = 0; i < ref.size(); ++i) EXPECT_NEAR(y.data[i], ref[i], 1e-5);
  conv.Backward(x, dy, &dx, true);
  auto loss = [&] {
    return Dot(RefConv(xd, n, cin, h, w, wd, bd, cout, kernel), dy.data);
  };
  ExpectClose(dx.data, NumericGradient(&xd, loss), "conv dx");
  ExpectClose(conv.weight.grad, NumericGradient(&wd, loss), "conv dweight");
  ExpectClose(conv.bias.grad, NumericGradient(&bd, loss), "conv dbias");
}

TEST(Conv2dTest, Kernel3MatchesReferenceAndFiniteDifferences) { CheckConv(3); }
TEST(Conv2dTest, Kernel1MatchesReferenceAndFiniteDifferences) { CheckConv(1); }
// Padding wider than the image (5x5 kernel on 1x1, 1x3 and 2x1 inputs): the
// im2col wrote past its row there (found by the CUDA feature decoder's
// parity test, whose CPU side then read garbage and crashed in free()).
TEST(Conv2dTest, KernelWiderThanTheImageMatchesReference) {
  CheckConv(5, 1, 1);
  CheckConv(5, 1, 3);
  CheckConv(5, 2, 1);
}

// Reference batch norm in double (batch statistics or given ones).
std::vector<double> RefBatchNorm(const std::vector<double>& x, int n, int c,
                                 int hw, const std::vector<double>& gamma,
                                 const std::vector<double>& beta, bool training,
                                 const std::vector<float>& rmean,
                                 const std::vector<float>& rvar) {
  std::vector<double> y(x.size());
  for (int ch = 0; ch < c; ++ch) {
    double mean = rmean[ch], var = rvar[ch];
    if (training) {
      mean = 0, var = 0;
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < hw; ++i) mean += x[(size_t(b) * c + ch) * hw + i];
      mean /= double(n) * hw;
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < hw; ++i) {
          const double d = x[(size_t(b) * c + ch) * hw + i] - mean;
          var += d * d;
        }
      var /= double(n) * hw;
    }
    for (int b = 0; b < n; ++b)
      for (int i = 0; i < hw; ++i) {
        const size_t k = (size_t(b) * c + ch) * hw + i;
        y[k] = gamma[ch] * (x[k] - mean) / std::sqrt(var + 1e-5) + beta[ch];
      }
  }
  return y;
}

void CheckBatchNorm(bool training) {
  std::mt19937 rng(5);
  const int n = 3, c = 2, h = 3, w = 4;
  BatchNorm2d bn("bn", c);
  bn.gamma.value = {1.5f, -0.7f};
  bn.beta.value = {0.2f, 0.3f};
  bn.running_mean.value = {0.1f, -0.2f};
  bn.running_var.value = {0.8f, 1.3f};
  const std::vector<float> rmean = bn.running_mean.value,
                           rvar = bn.running_var.value;
  Tensor x = RandomTensor(n, c, h, w, &rng, 2.f);
  Tensor dy = RandomTensor(n, c, h, w, &rng), y, dx;
  bn.Forward(x, &y, training);
  std::vector<double> xd = ToDouble(x.data), gd = ToDouble(bn.gamma.value),
                      bd = ToDouble(bn.beta.value);
  auto ref = [&] {
    return RefBatchNorm(xd, n, c, h * w, gd, bd, training, rmean, rvar);
  };
  const std::vector<double> expected = ref();
  for (size_t i = 0; i < expected.size(); ++i)
    EXPECT_NEAR(y.data[i], expected[i], 1e-5);
  bn.Backward(x, dy, &dx, true, training);
  auto loss = [&] { return Dot(ref(), dy.data); };
  ExpectClose(dx.data, NumericGradient(&xd, loss), "bn dx");
  ExpectClose(bn.gamma.grad, NumericGradient(&gd, loss), "bn dgamma");
  ExpectClose(bn.beta.grad, NumericGradient(&bd, loss), "bn dbeta");
  if (training) {
    // Running statistics: momentum 0.1, unbiased batch variance.
    for (int ch = 0; ch < c; ++ch) {
      double mean = 0, sq = 0;
      const int m = n * h * w;
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < h * w; ++i) mean += x.Plane(b, ch)[i];
      mean /= m;
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < h * w; ++i)
          sq += (x.Plane(b, ch)[i] - mean) * (x.Plane(b, ch)[i] - mean);
      EXPECT_NEAR(bn.running_mean.value[ch], 0.9 * rmean[ch] + 0.1 * mean,
                  1e-6);
      EXPECT_NEAR(bn.running_var.value[ch], 0.9 * rvar[ch] + 0.1 * sq / (m - 1),
                  1e-5);
    }
  } else {
    EXPECT_EQ(bn.running_mean.value, rmean);
  }
}

TEST(BatchNorm2dTest, TrainingModeGradients) { CheckBatchNorm(true); }
TEST(BatchNorm2dTest, InferenceModeGradients) { CheckBatchNorm(false); }

TEST(ReluTest, GradientMatchesFiniteDifferences) {
  std::mt19937 rng(7);
  Tensor x = RandomTensor(1, 2, 3, 3, &rng);
  for (float& v : x.data)
    if (std::abs(v) < 0.05f) v = 0.3f;  // away from the kink
  Tensor y = x, dy = RandomTensor(1, 2, 3, 3, &rng);
  ReluForward(&y);
  Tensor dx = dy;
  ReluBackward(y, &dx);
  std::vector<double> xd = ToDouble(x.data);
  auto loss = [&] {
    double s = 0;
    for (size_t i = 0; i < xd.size(); ++i)
      s += std::max(xd[i], 0.0) * dy.data[i];
    return s;
  };
  ExpectClose(dx.data, NumericGradient(&xd, loss), "relu dx");
}

TEST(PoolLinearTest, GradientsMatchFiniteDifferences) {
  std::mt19937 rng(9);
  const int n = 2, c = 3, h = 4, w = 5, out = 4;
  Linear linear("fc", c, out, &rng);
  Tensor x = RandomTensor(n, c, h, w, &rng), pooled, y, dpooled, dx;
  Tensor dy = RandomTensor(n, out, 1, 1, &rng);
  GlobalAvgPoolForward(x, &pooled);
  linear.Forward(pooled, &y);
  linear.Backward(pooled, dy, &dpooled, true);
  GlobalAvgPoolBackward(dpooled, x, &dx);
  std::vector<double> xd = ToDouble(x.data), wd = ToDouble(linear.weight.value),
                      bd = ToDouble(linear.bias.value);
  auto ref = [&] {
    std::vector<double> result(size_t(n) * out);
    for (int b = 0; b < n; ++b)
      for (int o = 0; o < out; ++o) {
        double s = bd[o];
        for (int i = 0; i < c; ++i) {
          double mean = 0;
          for (int p = 0; p < h * w; ++p)
            mean += xd[(size_t(b) * c + i) * h * w + p];
          s += wd[size_t(o) * c + i] * mean / (h * w);
        }
        result[size_t(b) * out + o] = s;
      }
    return result;
  };
  const std::vector<double> expected = ref();
  for (size_t i = 0; i < expected.size(); ++i)
    EXPECT_NEAR(y.data[i], expected[i], 1e-5);
  auto loss = [&] { return Dot(ref(), dy.data); };
  ExpectClose(dx.data, NumericGradient(&xd, loss), "pool+linear dx");
  ExpectClose(linear.weight.grad, NumericGradient(&wd, loss), "linear dweight");
  ExpectClose(linear.bias.grad, NumericGradient(&bd, loss), "linear dbias");
}

TEST(LossTest, BceWithLogitsGradientMatchesFiniteDifferences) {
  Tensor logits(1, 6, 1, 1);
  logits.data = {-3.f, -0.5f, 0.f, 0.7f, 2.f, 8.f};
  const std::vector<float> targets = {0, 1, 1, 0, 1, 0};
  Tensor grad;
  const double value = BceWithLogits(logits, targets, &grad);
  std::vector<double> z = ToDouble(logits.data);
  auto loss = [&] {
    double s = 0;
    for (size_t i = 0; i < z.size(); ++i) {
      const double p = 1.0 / (1.0 + std::exp(-z[i]));
      s -= targets[i] * std::log(p) + (1 - targets[i]) * std::log(1 - p);
    }
    return s / double(z.size());
  };
  EXPECT_NEAR(value, loss(), 1e-9);
  ExpectClose(grad.data, NumericGradient(&z, loss), "bce dlogits");
}

TEST(LossTest, BceWithLogitsSaturatedLogitsStayFinite) {
  Tensor logits(1, 4, 1, 1);
  logits.data = {100.f, -100.f, 100.f, -100.f};
  const std::vector<float> targets = {0, 1, 1, 0};
  Tensor grad;
  const double value = BceWithLogits(logits, targets, &grad);
  // Two wrong bits at |z| = 100 cost 100 each; two right ones ~exp(-100).
  EXPECT_NEAR(value, 200.0 / 4, 1e-9);
  EXPECT_FLOAT_EQ(grad.data[0], 0.25f);
  EXPECT_FLOAT_EQ(grad.data[1], -0.25f);
  EXPECT_TRUE(std::isfinite(grad.data[2]) && std::abs(grad.data[2]) < 1e-30f);
  EXPECT_TRUE(std::isfinite(grad.data[3]) && std::abs(grad.data[3]) < 1e-30f);
}

TEST(LossTest, MseGradientMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  Tensor a = RandomTensor(1, 2, 2, 3, &rng), b = RandomTensor(1, 2, 2, 3, &rng);
  Tensor grad;
  MseLoss(a, b, &grad);
  std::vector<double> ad = ToDouble(a.data);
  auto loss = [&] {
    double s = 0;
    for (size_t i = 0; i < ad.size(); ++i)
      s += (ad[i] - b.data[i]) * (ad[i] - b.data[i]);
    return s / double(ad.size());
  };
  ExpectClose(grad.data, NumericGradient(&ad, loss), "mse da");
}

// The convolution's bias gradient (row sums of dy) must not depend on where
// dy sits in memory, or training runs differ in their last bits between
// processes. Rows of odd length at every float offset of a 64-byte line.
TEST(RowSumsTest, BitIdenticalAtEveryBufferOffset) {
  const int rows = 32;
  const size_t length = 37 * 29;
  std::mt19937 rng(5);
  std::normal_distribution<float> normal(0.f, 1.f);
  std::vector<float> values(rows * length);
  for (float& v : values) v = normal(rng);
  std::vector<float> reference;
  for (int offset = 0; offset < 16; ++offset) {
    std::vector<float> buffer(offset + values.size());
    std::copy(values.begin(), values.end(), buffer.begin() + offset);
    std::vector<float> sums(rows, 0.5f);
    AddRowSums(buffer.data() + offset, rows, length, sums.data());
    if (offset == 0) {
      reference = sums;
      for (int r = 0; r < rows; ++r) {
        double exact = 0.5;
        for (size_t i = 0; i < length; ++i) exact += values[r * length + i];
        EXPECT_NEAR(sums[r], exact, 1e-3) << "row " << r;
      }
    }
    EXPECT_EQ(std::memcmp(sums.data(), reference.data(), rows * sizeof(float)),
              0)
        << "offset " << offset;
  }
}

TEST(AdamTest, FirstStepMovesByLearningRateAgainstTheGradientSign) {
  Parameter p("p", {3});
  p.value = {1.f, 2.f, 3.f};
  p.grad = {0.5f, -4.f, 1e-3f};
  Parameter buffer("b", {1}, false);
  NetworkAdam adam({&p, &buffer}, 0.01f);
  adam.Step();
  // Bias-corrected first step: m_hat / sqrt(v_hat) = sign(g).
  EXPECT_NEAR(p.value[0], 0.99f, 1e-6);
  EXPECT_NEAR(p.value[1], 2.01f, 1e-6);
  EXPECT_NEAR(p.value[2], 2.99f, 1e-4);
  adam.ZeroGrad();
  EXPECT_EQ(p.grad, std::vector<float>(3, 0.f));
}

}  // namespace
}  // namespace watergs
