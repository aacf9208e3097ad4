// Image losses for training and evaluation: L1, SSIM (Inria's ssim()), the
// 3DGS training loss (1 - lambda) * L1 + lambda * (1 - SSIM) with analytic
// gradients, and PSNR.
//
// SSIM follows Inria's gaussian-splatting utils/loss_utils.py exactly: an
// 11x11 Gaussian window (sigma 1.5, normalised to sum 1), applied per channel
// as a correlation with zero padding of 5 pixels ("same" output size, so
// border windows see zeros), C1 = 0.01^2, C2 = 0.03^2, and the mean of the
// SSIM map over all pixels and channels.
#pragma once

#include <vector>

#include "gaussian/image.h"

namespace watergs {

// Side of the SSIM window and its Gaussian sigma.
constexpr int kSsimWindow = 11;
constexpr double kSsimSigma = 1.5;

// Images are `height` rows of `width * channels` interleaved values (HWC).
// Returns mean SSIM(x, y); if grad_x is non-null it receives d(mean SSIM)/dx
// with x's shape (overwritten). Deterministic for any thread count.
template <typename T>
double SsimInterleaved(const T* x, const T* y, int width, int height,
                       int channels, T* grad_x);

// Mean absolute difference; grad (if non-null, overwritten) gets
// d(mean |x - y|)/dx = sign(x - y) / count, with sign(0) = 0.
template <typename T>
double L1Interleaved(const T* x, const T* y, size_t count, T* grad_x);

// Mean SSIM of two images of equal size; grad_a as above.
double Ssim(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a = nullptr);

// Mean |a - b| over pixels and channels.
double L1(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a = nullptr);

// Error ("loss: image sizes differ ...", as the losses say it) unless
// `image` is width x height with 3 values per pixel.
void CheckImageSize(int width, int height, const ImageRGB& image);

// PSNR in dB of `rendered` (clamped to [0, 1] first, as Inria evaluates)
// against `truth`: 20 log10(1 / sqrt(MSE)); +inf for identical images.
double Psnr(const ImageRGB& rendered, const ImageRGB& truth);

struct LossTerms {
  // Mean absolute error.
  double l1 = 0;
  // Mean SSIM.
  double ssim = 0;
  // (1 - lambda) * l1 + lambda * (1 - ssim).
  double total = 0;
};

// The training loss of 3DGS. Keeps scratch buffers between calls so that a
// training step does not allocate.
class TrainingLoss {
 public:
  // Weight of the D-SSIM term (Inria's lambda_dssim).
  explicit TrainingLoss(double lambda = 0.2) : lambda_(lambda) {}
  // Loss of `rendered` against `truth` (same size); grad (if non-null) is
  // resized to rendered's shape and receives dLoss/d(rendered).
  LossTerms Evaluate(const ImageRGB& rendered, const ImageRGB& truth,
                     ImageRGB* grad);

 private:
  double lambda_;
  std::vector<float> ssim_grad_;
};

}  // namespace watergs
