// Builds a steerable random-feature decoder (feature_decoder.h) from a folder
// of natural photos, and measures what WATER-GS needs of any decoder:
// balance on unmarked images (fair, uncorrelated bits, false positives) and
// steerability (how small a pixel change sets a message). Deterministic for
// a photo set and seed: `watergs make_decoder` is this plus file output.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "watermark/bit_decoder.h"
#include "watermark/feature_decoder.h"
#include "watermark/message.h"

namespace watergs {

struct FeatureCalibrationOptions {
  FeatureDecoderConfig config;
  // Side of the square photo crops the statistics are taken over.
  int crop = 128;
  // Crops for the convolution's standardisation and for the mean and
  // covariance of the pooled features.
  int normalisation_crops = 256;
  int feature_crops = 8192;
  // Covariance eigenvalues below floor x (their mean) are raised to it
  // before whitening: the smallest directions, estimated from few crops,
  // would otherwise be amplified without bound.
  double whiten_floor = 1e-5;
  // Standard deviation of each logit on the calibration crops.
  double logit_scale = 4.0;
  // 0: the logits read random orthonormal directions of all of whitened
  // feature space. K > 0: random orthonormal directions within the K
  // whitened directions of largest input gradient on photo crops (the most
  // steerable ones, found over steering_crops crops); still zero-mean,
  // uncorrelated and of standard deviation logit_scale on photos.
  int steerable_subspace = 0;
  int steering_crops = 16;
  // 0: photo crops as they are. S > 0: each calibration crop blurred by a
  // Gaussian of standard deviation drawn uniformly from [0, S] pixels, so
  // that the whitening also covers how smooth renders vary (a 3DGS render
  // is softer than a photo; directions photos never move are amplified by
  // the whitening and lean on renders).
  double calibration_blur = 0;
  // Seeds the convolution, the crops and the projection.
  uint32_t seed = 0;
};

struct FeatureCalibrationReport {
  int photos_used = 0;
  // Covariance eigenvalues of the pooled features (largest, smallest, and
  // how many were raised to the floor).
  double max_eigenvalue = 0, min_eigenvalue = 0;
  int floored_eigenvalues = 0;
  double seconds = 0;
};

// Random crops (side `crop`) of `photos` (float RGB in [0, 1], CV_32FC3, as
// LoadPhotoFolder decodes them: the one conversion), `count` of them,
// drawn deterministically from `seed`; photos smaller than the crop are
// skipped (Error if none is large enough).
std::vector<ImageRGB> SamplePhotoCrops(const std::vector<cv::Mat>& photos,
                                       int crop, int count, uint32_t seed);

// `crops` each blurred in place by a Gaussian of standard deviation drawn
// uniformly from [0, max_sigma] pixels (deterministic from `seed`; sigmas
// under 0.05 leave a crop as it is).
void BlurCropsRandomly(std::vector<ImageRGB>* crops, double max_sigma,
                       uint32_t seed);

// The calibrated network.
std::unique_ptr<FeatureNet> CalibrateFeatureDecoder(
    const std::vector<cv::Mat>& photos,
    const FeatureCalibrationOptions& options,
    FeatureCalibrationReport* report = nullptr);

// How a decoder reads unmarked images.
struct DecoderBalance {
  int images = 0;
  // Fraction of decoded 1-bits over all images and bits.
  double ones_fraction = 0;
  // Mean over bit pairs of |Pearson correlation| of their logits.
  double mean_abs_correlation = 0;
  // Largest fraction of 1-bits of any single bit position, and smallest.
  double max_bit_ones = 0, min_bit_ones = 1;
  // Images whose bits match `claimed` closely enough for "present" at
  // present_p, and the smallest bit-error count seen.
  int false_positives = 0;
  int min_bit_errors = 0;
  // The bits each image reads (logit > 0 -> 1), in the images' order.
  std::vector<Bits> image_bits;
  // The lean: per bit, the mean of the logits over the images and their
  // standard deviation (what a blind embedding must overcome at every view,
  // and how much it moves from one view to the next).
  std::vector<double> bit_mean, bit_std;
};
DecoderBalance MeasureBalance(BitDecoder& decoder,
                              const std::vector<ImageRGB>& images,
                              const Bits& claimed, double present_p = 1e-6);

struct SteerResult {
  int steps = 0;
  int bit_errors = 0;
  double psnr = 0;
  ImageRGB image;
};
// Pixel-space Adam on `image` (kept in [0, 1]) until every logit agrees with
// `target` by `margin` or `max_steps`: the steerability probe.
SteerResult SteerPixels(BitDecoder& decoder, const ImageRGB& image,
                        const Bits& target, int max_steps, double lr,
                        double margin);

}  // namespace watergs
