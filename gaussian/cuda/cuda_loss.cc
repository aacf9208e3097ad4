// Host side of the CUDA training loss (see cuda_loss.h); kernels in loss.cu.
#include "gaussian/cuda/cuda_loss.h"

#include <cmath>
#include <string>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/loss_kernels.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;

// loss.cc's GaussianWindow<float>: taps in double, normalised, then rounded.
cuda_loss::SsimWindow Window() {
  constexpr int kRadius = kSsimWindow / 2;
  double g[kSsimWindow], sum = 0;
  for (int k = 0; k < kSsimWindow; ++k) {
    const double d = k - kRadius;
    g[k] = std::exp(-d * d / (2 * kSsimSigma * kSsimSigma));
    sum += g[k];
  }
  cuda_loss::SsimWindow window;
  for (int k = 0; k < kSsimWindow; ++k) {
    window.g[k] = static_cast<float>(g[k] / sum);
  }
  return window;
}

void CheckSameSize(const ImageRGB& a, const ImageRGB& b) {
  if (a.width != b.width || a.height != b.height ||
      a.data.size() != b.data.size()) {
    Fail("loss (cuda): image sizes differ (" + std::to_string(a.width) + "x" +
         std::to_string(a.height) + " vs " + std::to_string(b.width) + "x" +
         std::to_string(b.height) + ")");
  }
}

void PrepareGrad(const ImageRGB& like, ImageRGB* grad) {
  grad->width = like.width;
  grad->height = like.height;
  grad->data.resize(like.data.size());
}

float InverseCount(size_t count) {
  return static_cast<float>(1.0 / static_cast<double>(count));
}

}  // namespace

double CudaTrainingLoss::MeanOfMapPlane(size_t count) {
  const float* map = scratch_.data() + 8 * count;
  partials_.Resize(cuda_loss::kMaxPartials);
  sum_.Resize(1);
  WATERGS_CUDA_CHECK(cuda_loss::LaunchDeterministicSum(
      map, count, partials_.data(), sum_.data(), nullptr));
  double sum = 0;
  WATERGS_CUDA_CHECK(
      cudaMemcpy(&sum, sum_.data(), sizeof(double), cudaMemcpyDeviceToHost));
  return sum / static_cast<double>(count);
}

double CudaTrainingLoss::L1Device(const float* x, const float* y, size_t count,
                                  float* grad) {
  if (count == 0) return 0.0;
  if (scratch_.size() < 9 * count) scratch_.Resize(9 * count);
  WATERGS_CUDA_CHECK(cuda_loss::LaunchL1(x, y, count, InverseCount(count),
                                         scratch_.data() + 8 * count, grad,
                                         nullptr));
  return MeanOfMapPlane(count);
}

LossTerms CudaTrainingLoss::MseDevice(const float* x, const float* y,
                                      size_t count, double weight,
                                      float* grad) {
  LossTerms terms;
  if (count == 0) return terms;
  if (scratch_.size() < 9 * count) scratch_.Resize(9 * count);
  // The L1 column first (the host term reports it too), then the squares.
  WATERGS_CUDA_CHECK(cuda_loss::LaunchL1(
      x, y, count, 0.f, scratch_.data() + 8 * count, nullptr, nullptr));
  terms.l1 = MeanOfMapPlane(count);
  WATERGS_CUDA_CHECK(cuda_loss::LaunchSquaredError(
      x, y, count, static_cast<float>(2 * weight / double(count)),
      scratch_.data() + 8 * count, grad, nullptr));
  terms.total = weight * MeanOfMapPlane(count);
  return terms;
}

double CudaTrainingLoss::SsimDevice(const float* x, const float* y, int width,
                                    int height, int channels, float* grad) {
  if (width <= 0 || height <= 0 || channels <= 0) return 1.0;
  const size_t count = static_cast<size_t>(width) * height * channels;
  if (scratch_.size() < cuda_loss::kSsimScratchPlanes * count) {
    scratch_.Resize(cuda_loss::kSsimScratchPlanes * count);
  }
  const cuda_loss::SsimWindow window = Window();
  WATERGS_CUDA_CHECK(cuda_loss::LaunchSsimForward(
      x, y, width, height, channels, window, static_cast<float>(kC1),
      static_cast<float>(kC2), InverseCount(count), grad != nullptr,
      scratch_.data(), nullptr));
  const double ssim = MeanOfMapPlane(count);
  if (grad) {
    WATERGS_CUDA_CHECK(cuda_loss::LaunchSsimBackward(
        x, y, width, height, channels, window, scratch_.data(), false, 0.f, 0.f,
        grad, nullptr));
  }
  return ssim;
}

LossTerms CudaTrainingLoss::EvaluateDevice(const float* rendered,
                                           const float* truth, int width,
                                           int height, float* grad) {
  if (width < 0 || height < 0) {
    Fail("loss (cuda): negative image size " + std::to_string(width) + "x" +
         std::to_string(height));
  }
  LossTerms terms;
  const size_t count = static_cast<size_t>(width) * height * 3;
  terms.l1 = L1Device(rendered, truth, count, grad);
  if (!grad) {
    terms.ssim = SsimDevice(rendered, truth, width, height, 3, nullptr);
  } else if (count == 0) {
    terms.ssim = 1.0;
  } else {
    // SsimDevice's steps, with the backward adding into the L1 gradient.
    const cuda_loss::SsimWindow window = Window();
    WATERGS_CUDA_CHECK(cuda_loss::LaunchSsimForward(
        rendered, truth, width, height, 3, window, static_cast<float>(kC1),
        static_cast<float>(kC2), InverseCount(count), true, scratch_.data(),
        nullptr));
    terms.ssim = MeanOfMapPlane(count);
    WATERGS_CUDA_CHECK(cuda_loss::LaunchSsimBackward(
        rendered, truth, width, height, 3, window, scratch_.data(), true,
        static_cast<float>(1.0 - lambda_), static_cast<float>(-lambda_), grad,
        nullptr));
  }
  terms.total = (1.0 - lambda_) * terms.l1 + lambda_ * (1.0 - terms.ssim);
  return terms;
}

LossTerms CudaTrainingLoss::Evaluate(const ImageRGB& rendered,
                                     const ImageRGB& truth, ImageRGB* grad) {
  CheckSameSize(rendered, truth);
  rendered_.Upload(rendered.data);
  truth_.Upload(truth.data);
  if (grad) grad_.Resize(rendered.data.size());
  const LossTerms terms =
      EvaluateDevice(rendered_.data(), truth_.data(), rendered.width,
                     rendered.height, grad ? grad_.data() : nullptr);
  if (grad) {
    PrepareGrad(rendered, grad);
    grad_.Download(&grad->data);
  }
  return terms;
}

double CudaSsim(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a) {
  CheckSameSize(a, b);
  CudaTrainingLoss loss;
  DeviceBuffer<float> da, db, dg;
  da.Upload(a.data);
  db.Upload(b.data);
  if (grad_a) dg.Resize(a.data.size());
  const double ssim = loss.SsimDevice(da.data(), db.data(), a.width, a.height,
                                      3, grad_a ? dg.data() : nullptr);
  if (grad_a) {
    PrepareGrad(a, grad_a);
    dg.Download(&grad_a->data);
  }
  return ssim;
}

double CudaL1(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a) {
  CheckSameSize(a, b);
  CudaTrainingLoss loss;
  DeviceBuffer<float> da, db, dg;
  da.Upload(a.data);
  db.Upload(b.data);
  if (grad_a) dg.Resize(a.data.size());
  const double l1 = loss.L1Device(da.data(), db.data(), a.data.size(),
                                  grad_a ? dg.data() : nullptr);
  if (grad_a) {
    PrepareGrad(a, grad_a);
    dg.Download(&grad_a->data);
  }
  return l1;
}

}  // namespace watergs
