// Parity of the GPU neural-network layers (watermark/cuda/cuda_nn.h) with
// the CPU layers (nn_layers.h), which are themselves checked against finite
// differences: forward values, input gradients and weight gradients on
// random tensors of several shapes. Every test skips without a GPU.
//
// Tolerances, relative to the largest magnitude of the CPU tensor compared:
// - 1e-4 for convolutions and what depends on them: cuDNN sums the
//   in*k*k (or N*H*W) products in another order than Eigen and may pick
//   Winograd or FFT algorithms, whose FP32 error is ~1e-5 (direct and GEMM
//   algorithms: ~1e-6);
// - 1e-5 for BatchNorm (cuDNN reduces in float, the CPU in double) and
//   cuBLAS Linear;
// - 1e-6 (float rounding) where both sides evaluate the same formula in the
//   same precision: running statistics, pooling, BCE, MSE, Adam (which may
//   differ by an FMA contraction);
// - exact for ReLU.
#ifdef WATERGS_WITH_CUDA

#include "watermark/cuda/cuda_nn.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "tests/common/cuda_test.h"
#include "watermark/nn_layers.h"

namespace watergs {
namespace {

Tensor RandomTensor(int n, int c, int h, int w, std::mt19937* rng,
                    float mean = 0.f, float scale = 1.f) {
  Tensor t(n, c, h, w);
  std::normal_distribution<float> dist(mean, scale);
  for (float& v : t.data) v = dist(*rng);
  return t;
}

void Randomize(std::vector<float>* values, std::mt19937* rng, float low,
               float high) {
  std::uniform_real_distribution<float> dist(low, high);
  for (float& v : *values) v = dist(*rng);
}

DeviceTensor ToDevice(const Tensor& host) {
  DeviceTensor t;
  t.Upload(host);
  return t;
}

std::vector<float> ToHost(const DeviceTensor& t) {
  Tensor host;
  t.Download(&host);
  return host.data;
}

std::vector<float> ToHost(const DeviceBuffer<float>& buffer) {
  std::vector<float> host;
  buffer.Download(&host);
  return host;
}

// |gpu - cpu| <= relative * max|cpu| (+ a tiny floor for all-zero tensors)
// element-wise; reports the worst element.
void ExpectClose(const std::vector<float>& gpu, const std::vector<float>& cpu,
                 double relative, const std::string& what) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  double scale = 0.0;
  for (float v : cpu) scale = std::max(scale, double(std::abs(v)));
  const double tolerance = relative * scale + 1e-30;
  double worst = 0.0;
  size_t worst_index = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    ASSERT_TRUE(std::isfinite(gpu[i])) << what << " [" << i << "]";
    const double diff = std::abs(double(gpu[i]) - cpu[i]);
    if (diff > worst) worst = diff, worst_index = i;
  }
  EXPECT_LE(worst, tolerance)
      << what << ": worst element " << worst_index << " gpu "
      << gpu[worst_index] << " cpu " << cpu[worst_index] << " (max |cpu| "
      << scale << ")";
}

struct ConvCase {
  int n, in, out, kernel, h, w;
};
// How CTest lists a case ("N2_64to64_k3_9x10"), instead of its raw bytes.
void PrintTo(const ConvCase& c, std::ostream* os) {
  *os << "N" << c.n << "_" << c.in << "to" << c.out << "_k" << c.kernel << "_"
      << c.h << "x" << c.w;
}

class CudaConv2dTest : public ::testing::TestWithParam<ConvCase> {};

TEST_P(CudaConv2dTest, ForwardAndGradientsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  const ConvCase p = GetParam();
  std::mt19937 rng(11 + p.in * 7 + p.kernel);
  Conv2d cpu("conv", p.in, p.out, p.kernel, &rng);
  CudaNnContext context;
  CudaConv2d gpu(&context, cpu);
  const Tensor x = RandomTensor(p.n, p.in, p.h, p.w, &rng);
  const Tensor dy = RandomTensor(p.n, p.out, p.h, p.w, &rng);
  const DeviceTensor x_gpu = ToDevice(x), dy_gpu = ToDevice(dy);

  Tensor y;
  DeviceTensor y_gpu;
  cpu.Forward(x, &y);
  gpu.Forward(x_gpu, &y_gpu);
  EXPECT_EQ(y_gpu.n, p.n);
  EXPECT_EQ(y_gpu.c, p.out);
  ExpectClose(ToHost(y_gpu), y.data, 1e-4, "conv forward");

  // Twice: the weight gradients must accumulate (cuDNN beta = 1).
  Tensor dx;
  DeviceTensor dx_gpu;
  for (int pass = 0; pass < 2; ++pass) {
    cpu.Backward(x, dy, &dx, true);
    gpu.Backward(x_gpu, dy_gpu, &dx_gpu, true);
  }
  ExpectClose(ToHost(dx_gpu), dx.data, 1e-4, "conv input gradient");
  ExpectClose(ToHost(gpu.weight.grad), cpu.weight.grad, 1e-4,
              "conv weight gradient");
  ExpectClose(ToHost(gpu.bias.grad), cpu.bias.grad, 1e-4, "conv bias gradient");

  // Input gradient only: the weight gradients stay as they were.
  const std::vector<float> weight_grad = ToHost(gpu.weight.grad);
  gpu.Backward(x_gpu, dy_gpu, &dx_gpu, false);
  EXPECT_EQ(ToHost(gpu.weight.grad), weight_grad);
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, CudaConv2dTest,
    ::testing::Values(ConvCase{1, 3, 8, 3, 5, 7},      // N=1, 3x3
                      ConvCase{2, 5, 4, 3, 1, 1},      // 1x1 spatial, 3x3
                      ConvCase{3, 6, 5, 1, 4, 4},      // 1x1 kernel, N>1
                      ConvCase{1, 4, 3, 1, 1, 1},      // 1x1 kernel, 1x1
                      ConvCase{2, 64, 64, 3, 9, 10},   // decoder-like
                      ConvCase{2, 59, 16, 3, 6, 5}));  // encoder concat-like

TEST(CudaConv2dPlanTest, SeveralInputSizesOnOneLayer) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(3);
  Conv2d cpu("conv", 4, 6, 3, &rng);
  CudaNnContext context;
  CudaConv2d gpu(&context, cpu);
  for (int size : {7, 3, 7, 12}) {
    const Tensor x = RandomTensor(2, 4, size, size + 1, &rng);
    Tensor y;
    DeviceTensor y_gpu;
    cpu.Forward(x, &y);
    gpu.Forward(ToDevice(x), &y_gpu);
    ExpectClose(ToHost(y_gpu), y.data, 1e-4,
                "conv forward at " + std::to_string(size));
  }
}

// N * H * W >= 3 in training: with two values per channel the normalised
// output is +-1 whatever x is, so dx is 0 and only rounding noise compares.
struct BnCase {
  int n, c, h, w;
};
// How CTest lists a case ("N3_C64_9x8").
void PrintTo(const BnCase& c, std::ostream* os) {
  *os << "N" << c.n << "_C" << c.c << "_" << c.h << "x" << c.w;
}

class CudaBatchNormTest : public ::testing::TestWithParam<BnCase> {
 protected:
  // A CPU layer with random affine parameters and running statistics.
  static BatchNorm2d RandomLayer(int channels, std::mt19937* rng) {
    BatchNorm2d bn("bn", channels);
    Randomize(&bn.gamma.value, rng, 0.5f, 1.5f);
    Randomize(&bn.beta.value, rng, -0.5f, 0.5f);
    Randomize(&bn.running_mean.value, rng, -1.f, 1.f);
    Randomize(&bn.running_var.value, rng, 0.5f, 2.f);
    return bn;
  }
};

TEST_P(CudaBatchNormTest, TrainingModeMatchesCpuWithRunningUpdate) {
  WATERGS_REQUIRE_CUDA();
  const BnCase p = GetParam();
  std::mt19937 rng(5 + p.n * 13 + p.h);
  BatchNorm2d cpu = RandomLayer(p.c, &rng);
  CudaNnContext context;
  CudaBatchNorm2d gpu(&context, cpu);
  // Off-centre input, so the mean and the unbiased variance both matter.
  const Tensor x = RandomTensor(p.n, p.c, p.h, p.w, &rng, 3.f, 2.f);
  const Tensor dy = RandomTensor(p.n, p.c, p.h, p.w, &rng);
  const DeviceTensor x_gpu = ToDevice(x), dy_gpu = ToDevice(dy);

  Tensor y;
  DeviceTensor y_gpu;
  cpu.Forward(x, &y, true);
  gpu.Forward(x_gpu, &y_gpu, true);
  ExpectClose(ToHost(y_gpu), y.data, 1e-5, "bn training forward");
  ExpectClose(ToHost(gpu.running_mean.value), cpu.running_mean.value, 1e-6,
              "running mean");
  ExpectClose(ToHost(gpu.running_var.value), cpu.running_var.value, 1e-6,
              "running variance (unbiased)");

  Tensor dx;
  DeviceTensor dx_gpu;
  cpu.Backward(x, dy, &dx, true, true);
  gpu.Backward(x_gpu, dy_gpu, &dx_gpu, true, true);
  ExpectClose(ToHost(dx_gpu), dx.data, 1e-5, "bn training input gradient");
  ExpectClose(ToHost(gpu.gamma.grad), cpu.gamma.grad, 1e-5, "gamma gradient");
  ExpectClose(ToHost(gpu.beta.grad), cpu.beta.grad, 1e-5, "beta gradient");

  // Without weight gradients: dx again, gradients untouched.
  const std::vector<float> gamma_grad = ToHost(gpu.gamma.grad);
  gpu.Backward(x_gpu, dy_gpu, &dx_gpu, false, true);
  ExpectClose(ToHost(dx_gpu), dx.data, 1e-5, "bn input gradient only");
  EXPECT_EQ(ToHost(gpu.gamma.grad), gamma_grad);
}

TEST_P(CudaBatchNormTest, InferenceModeMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  const BnCase p = GetParam();
  std::mt19937 rng(7 + p.n * 13 + p.h);
  BatchNorm2d cpu = RandomLayer(p.c, &rng);
  CudaNnContext context;
  CudaBatchNorm2d gpu(&context, cpu);
  const Tensor x = RandomTensor(p.n, p.c, p.h, p.w, &rng, 0.5f, 1.5f);
  const Tensor dy = RandomTensor(p.n, p.c, p.h, p.w, &rng);
  const DeviceTensor x_gpu = ToDevice(x), dy_gpu = ToDevice(dy);

  Tensor y, dx;
  DeviceTensor y_gpu, dx_gpu;
  cpu.Forward(x, &y, false);
  gpu.Forward(x_gpu, &y_gpu, false);
  ExpectClose(ToHost(y_gpu), y.data, 1e-5, "bn inference forward");
  // Inference mode leaves the running statistics alone.
  EXPECT_EQ(ToHost(gpu.running_mean.value), cpu.running_mean.value);
  EXPECT_EQ(ToHost(gpu.running_var.value), cpu.running_var.value);

  cpu.Backward(x, dy, &dx, true, false);
  gpu.Backward(x_gpu, dy_gpu, &dx_gpu, true, false);
  ExpectClose(ToHost(dx_gpu), dx.data, 1e-6, "bn inference input gradient");
  ExpectClose(ToHost(gpu.gamma.grad), cpu.gamma.grad, 1e-6, "gamma gradient");
  ExpectClose(ToHost(gpu.beta.grad), cpu.beta.grad, 1e-6, "beta gradient");
}

INSTANTIATE_TEST_SUITE_P(Shapes, CudaBatchNormTest,
                         ::testing::Values(BnCase{3, 3, 1, 1},  // 1x1, N>1
                                           BnCase{1, 4, 5, 7},  // N=1
                                           BnCase{3, 5, 4, 4},  // N>1
                                           BnCase{2, 64, 9, 8}));

TEST(CudaBatchNormTest, TrainingOnOneValuePerChannelIsRefused) {
  WATERGS_REQUIRE_CUDA();
  BatchNorm2d cpu("bn", 2);
  CudaNnContext context;
  CudaBatchNorm2d gpu(&context, cpu);
  DeviceTensor x(1, 2, 1, 1), y;
  x.data.Zero();
  EXPECT_THROW(gpu.Forward(x, &y, true), Error);
}

TEST(CudaActivationTest, ReluAndPoolingMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(17);
  for (const BnCase& s : {BnCase{1, 3, 1, 1}, BnCase{3, 5, 6, 7}}) {
    Tensor x = RandomTensor(s.n, s.c, s.h, s.w, &rng);
    DeviceTensor x_gpu = ToDevice(x);
    ReluForward(&x);
    CudaReluForward(&x_gpu);
    EXPECT_EQ(ToHost(x_gpu), x.data) << "relu forward";
    Tensor dy = RandomTensor(s.n, s.c, s.h, s.w, &rng);
    DeviceTensor dy_gpu = ToDevice(dy);
    ReluBackward(x, &dy);
    CudaReluBackward(x_gpu, &dy_gpu);
    EXPECT_EQ(ToHost(dy_gpu), dy.data) << "relu backward";

    Tensor pooled, dpooled = RandomTensor(s.n, s.c, 1, 1, &rng), dx;
    DeviceTensor pooled_gpu, dx_gpu;
    GlobalAvgPoolForward(x, &pooled);
    CudaGlobalAvgPoolForward(x_gpu, &pooled_gpu);
    EXPECT_EQ(pooled_gpu.h, 1);
    ExpectClose(ToHost(pooled_gpu), pooled.data, 1e-6, "pool forward");
    GlobalAvgPoolBackward(dpooled, x, &dx);
    CudaGlobalAvgPoolBackward(ToDevice(dpooled), x_gpu, &dx_gpu);
    ExpectClose(ToHost(dx_gpu), dx.data, 1e-6, "pool backward");
  }
}

TEST(CudaLinearTest, ForwardAndGradientsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(19);
  for (int n : {1, 3}) {
    Linear cpu("linear", 7, 5, &rng);
    CudaNnContext context;
    CudaLinear gpu(&context, cpu);
    const Tensor x = RandomTensor(n, 7, 1, 1, &rng);
    const Tensor dy = RandomTensor(n, 5, 1, 1, &rng);
    const DeviceTensor x_gpu = ToDevice(x), dy_gpu = ToDevice(dy);
    Tensor y, dx;
    DeviceTensor y_gpu, dx_gpu;
    cpu.Forward(x, &y);
    gpu.Forward(x_gpu, &y_gpu);
    ExpectClose(ToHost(y_gpu), y.data, 1e-5, "linear forward");
    for (int pass = 0; pass < 2; ++pass) {
      cpu.Backward(x, dy, &dx, true);
      gpu.Backward(x_gpu, dy_gpu, &dx_gpu, true);
    }
    ExpectClose(ToHost(dx_gpu), dx.data, 1e-5, "linear input gradient");
    ExpectClose(ToHost(gpu.weight.grad), cpu.weight.grad, 1e-5,
                "linear weight gradient");
    ExpectClose(ToHost(gpu.bias.grad), cpu.bias.grad, 1e-5,
                "linear bias gradient");
  }
}

TEST(CudaLossTest, BceWithSaturatedLogitsIsFiniteAndMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  Tensor logits(2, 4, 1, 1);
  logits.data = {60.f, -60.f, 60.f, -60.f, 0.f, 2.5f, -1e3f, 0.3f};
  const std::vector<float> targets = {1.f, 0.f, 0.f, 1.f, 1.f, 0.f, 1.f, 0.3f};
  Tensor dlogits;
  const double loss = BceWithLogits(logits, targets, &dlogits);
  DeviceBuffer<float> targets_gpu;
  targets_gpu.Upload(targets);
  DeviceTensor dlogits_gpu;
  const double loss_gpu =
      CudaBceWithLogits(ToDevice(logits), targets_gpu, &dlogits_gpu);
  ASSERT_TRUE(std::isfinite(loss_gpu));
  EXPECT_NEAR(loss_gpu, loss, 1e-12 * loss);
  const std::vector<float> grad = ToHost(dlogits_gpu);
  for (float g : grad) EXPECT_TRUE(std::isfinite(g));
  ExpectClose(grad, dlogits.data, 1e-6, "bce gradient");
  // A confident right bit costs ~0, a confident wrong one ~60 (here /8).
  EXPECT_GT(loss_gpu, 2 * 60.0 / 8);
}

TEST(CudaLossTest, MseMatchesCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(23);
  const Tensor a = RandomTensor(2, 3, 5, 4, &rng);
  const Tensor b = RandomTensor(2, 3, 5, 4, &rng);
  Tensor da;
  const double loss = MseLoss(a, b, &da);
  DeviceTensor da_gpu;
  const double loss_gpu = CudaMseLoss(ToDevice(a), ToDevice(b), &da_gpu);
  EXPECT_NEAR(loss_gpu, loss, 1e-12 * loss);
  ExpectClose(ToHost(da_gpu), da.data, 1e-6, "mse gradient");
}

TEST(CudaNetworkAdamTest, StepsMatchCpu) {
  WATERGS_REQUIRE_CUDA();
  std::mt19937 rng(29);
  Parameter weight("w", {4, 9}), bias("b", {4}), buffer("r", {4}, false);
  for (Parameter* p : {&weight, &bias, &buffer})
    Randomize(&p->value, &rng, -1.f, 1.f);
  CudaParameter weight_gpu(weight), bias_gpu(bias), buffer_gpu(buffer);
  NetworkAdam cpu({&weight, &bias, &buffer}, 1e-2f);
  CudaNetworkAdam gpu({&weight_gpu, &bias_gpu, &buffer_gpu}, 1e-2f);
  for (int step = 0; step < 3; ++step) {
    cpu.ZeroGrad();
    gpu.ZeroGrad();
    for (Parameter* p : {&weight, &bias}) Randomize(&p->grad, &rng, -2.f, 2.f);
    weight.grad[5] = std::nanf("");  // counts as 0 on both
    weight_gpu.grad.Upload(weight.grad);
    bias_gpu.grad.Upload(bias.grad);
    cpu.Step();
    gpu.Step();
  }
  EXPECT_EQ(gpu.step, cpu.step);
  ExpectClose(ToHost(weight_gpu.value), weight.value, 1e-6, "adam weight");
  ExpectClose(ToHost(bias_gpu.value), bias.value, 1e-6, "adam bias");
  ExpectClose(ToHost(gpu.m[0]), cpu.m[0], 1e-6, "adam first moment");
  ExpectClose(ToHost(gpu.v[0]), cpu.v[0], 1e-6, "adam second moment");
  ExpectClose(ToHost(gpu.m[1]), cpu.m[1], 1e-6, "adam bias first moment");
  ExpectClose(ToHost(gpu.v[1]), cpu.v[1], 1e-6, "adam bias second moment");
  EXPECT_EQ(gpu.m[2].size(), 0u);  // no moments for buffers
  // Buffers are never optimised.
  EXPECT_EQ(ToHost(buffer_gpu.value), buffer.value);
}

}  // namespace
}  // namespace watergs

#endif  // WATERGS_WITH_CUDA
