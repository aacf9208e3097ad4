// The 3DGS training loss on a CUDA device: L1, SSIM (Inria's, as
// gaussian/loss.h defines it) and (1 - lambda) L1 + lambda (1 - SSIM) with
// the gradient w.r.t. the rendered image. The kernels follow loss.cc step by
// step (tests/gaussian/cuda_loss_test.cc checks parity with it); sums are
// reduced in an order fixed by the image size, so results are reproducible.
#pragma once

#include <cstddef>

#include "gaussian/cuda/device_buffer.h"
#include "gaussian/image.h"
#include "gaussian/loss.h"

namespace watergs {

class CudaTrainingLoss {
 public:
  // Weight of the D-SSIM term (Inria's lambda_dssim).
  explicit CudaTrainingLoss(double lambda = 0.2) : lambda_(lambda) {}

  // rendered, truth: device, height x width x 3 floats (HWC). grad (device,
  // nullable, same shape) is overwritten with dLoss/d(rendered). Waits for
  // the device to read the sums back.
  LossTerms EvaluateDevice(const float* rendered, const float* truth, int width,
                           int height, float* grad);
  // TrainingLoss::Evaluate's contract on host images (copies both ways).
  LossTerms Evaluate(const ImageRGB& rendered, const ImageRGB& truth,
                     ImageRGB* grad);

  // Device HWC images of `channels` values per pixel; as SsimInterleaved:
  // mean SSIM, grad (device, nullable) = d(mean SSIM)/dx, overwritten.
  double SsimDevice(const float* x, const float* y, int width, int height,
                    int channels, float* grad);
  // As L1Interleaved on `count` device values.
  double L1Device(const float* x, const float* y, size_t count, float* grad);
  // weight * mean (x - y)^2 over `count` device values (the embedder's MSE
  // term); grad (device, nullable) is overwritten with its derivative,
  // 2 weight (x - y) / count. LossTerms as the host term fills them.
  LossTerms MseDevice(const float* x, const float* y, size_t count,
                      double weight, float* grad);

 private:
  // Mean of the `count` floats of plane 8 of scratch_ (deterministic order).
  double MeanOfMapPlane(size_t count);

  double lambda_;
  // SSIM planes (kSsimScratchPlanes x values), reused between calls.
  DeviceBuffer<float> scratch_;
  // Partial sums and the total of the deterministic reduction.
  DeviceBuffer<double> partials_, sum_;
  // Device copies of host images for Evaluate.
  DeviceBuffer<float> rendered_, truth_, grad_;
};

// Ssim() and L1() of gaussian/loss.h computed on the device.
double CudaSsim(const ImageRGB& a, const ImageRGB& b,
                ImageRGB* grad_a = nullptr);
double CudaL1(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a = nullptr);

}  // namespace watergs
