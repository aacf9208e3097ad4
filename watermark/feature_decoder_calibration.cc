// Calibration and measurement of the random-feature decoder (see
// feature_decoder_calibration.h).
#include "watermark/feature_decoder_calibration.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "gaussian/util/error.h"
#include "watermark/network_image.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

using MatrixXd = Eigen::MatrixXd;
using VectorXd = Eigen::VectorXd;

// Sets the convolution so that each output channel has zero mean and unit
// variance over the pixels of `crops` (BatchNorm in inference mode, folded).
void StandardiseConvolution(const std::vector<ImageRGB>& crops,
                            FeatureNet* net) {
  const int channels = net->config().channels;
  std::vector<double> sum(channels, 0.0), sum_sq(channels, 0.0);
  double count = 0;
  Tensor input, y;
  for (const ImageRGB& crop : crops) {
    ImageToTensor(crop, false, &input);
    net->ConvolutionOutput(input, &y);
    const size_t hw = y.PlaneSize();
    for (int c = 0; c < channels; ++c) {
      const float* plane = y.Plane(0, c);
      double s = 0, s2 = 0;
      for (size_t i = 0; i < hw; ++i)
        s += plane[i], s2 += double(plane[i]) * plane[i];
      sum[c] += s, sum_sq[c] += s2;
    }
    count += double(hw);
  }
  const int fan_in = 3 * net->config().kernel * net->config().kernel;
  for (int c = 0; c < channels; ++c) {
    const double mean = sum[c] / count;
    const double var = std::max(sum_sq[c] / count - mean * mean, 0.0);
    const double inv_std = 1.0 / std::sqrt(var + 1e-5);
    float* w = &net->conv.weight.value[size_t(c) * fan_in];
    for (int i = 0; i < fan_in; ++i) w[i] = float(w[i] * inv_std);
    net->conv.bias.value[c] = float((net->conv.bias.value[c] - mean) * inv_std);
  }
}

// Pooled features [crops x C] of the network (before its linear layer).
MatrixXd PooledFeatures(const std::vector<ImageRGB>& crops, FeatureNet* net) {
  const int channels = net->config().channels;
  MatrixXd features(crops.size(), channels);
  Tensor input;
  for (size_t i = 0; i < crops.size(); ++i) {
    ImageToTensor(crops[i], false, &input);
    net->Forward(input);
    for (int c = 0; c < channels; ++c) features(i, c) = net->features().data[c];
  }
  return features;
}

// L x C matrix with orthonormal rows, from a Gaussian matrix's QR.
MatrixXd RandomOrthogonalRows(int rows, int cols, std::mt19937* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  MatrixXd g(cols, cols);
  for (int i = 0; i < cols; ++i)
    for (int j = 0; j < cols; ++j) g(i, j) = normal(*rng);
  Eigen::HouseholderQR<MatrixXd> qr(g);
  MatrixXd q = qr.householderQ() * MatrixXd::Identity(cols, cols);
  return q.leftCols(rows).transpose();
}

// C x k matrix with orthonormal columns spanning those of `m`.
MatrixXd Orthonormalised(const MatrixXd& m) {
  Eigen::HouseholderQR<MatrixXd> qr(m);
  return qr.householderQ() * MatrixXd::Identity(m.rows(), m.cols());
}

// E_x[J_x J_x^T] v for each column v of `directions` (C x k), J_x the
// Jacobian of the pooled features with respect to the input at crop x:
// J^T v by the network's backward pass, J (J^T v) by a central difference
// of the forward pass (ReLU's kinks average out over the crop's pixels).
MatrixXd FeatureJacobianGram(const std::vector<ImageRGB>& crops,
                             const MatrixXd& directions, FeatureNet* net) {
  const int channels = int(directions.rows()), k = int(directions.cols());
  MatrixXd out = MatrixXd::Zero(channels, k);
  Tensor input, dfeatures, moved;
  dfeatures.Resize(1, channels, 1, 1);
  std::vector<Tensor> gradients(k);
  for (const ImageRGB& crop : crops) {
    ImageToTensor(crop, false, &input);
    net->Forward(input);
    for (int j = 0; j < k; ++j) {
      for (int c = 0; c < channels; ++c)
        dfeatures.data[c] = float(directions(c, j));
      net->FeatureBackward(dfeatures, &gradients[j]);
    }
    for (int j = 0; j < k; ++j) {
      const Tensor& g = gradients[j];
      float largest = 0;
      for (float v : g.data) largest = std::max(largest, std::abs(v));
      if (largest == 0) continue;
      const float h = 1e-3f / largest;
      VectorXd difference(channels);
      for (int sign : {1, -1}) {
        moved = input;
        for (size_t i = 0; i < moved.data.size(); ++i)
          moved.data[i] += sign * h * g.data[i];
        net->Forward(moved);
        for (int c = 0; c < channels; ++c) {
          const double f = net->features().data[c];
          difference(c) = sign > 0 ? f : (difference(c) - f) / (2.0 * h);
        }
      }
      out.col(j) += difference / double(crops.size());
    }
  }
  return out;
}

// The k whitened feature directions (orthonormal columns, C x k) along which
// the decoder's input gradient is largest on photo crops, largest first: the
// top eigenvectors of W E[J J^T] W (W the whitening), by block subspace
// iteration and a Rayleigh-Ritz step. Logits along them move most per unit
// of pixel change while keeping unit variance on photos.
MatrixXd SteerableSubspace(const std::vector<ImageRGB>& crops,
                           const MatrixXd& whitening, int k, int rounds,
                           FeatureNet* net, std::mt19937* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  MatrixXd basis(whitening.rows(), k);
  for (int i = 0; i < basis.rows(); ++i)
    for (int j = 0; j < k; ++j) basis(i, j) = normal(*rng);
  basis = Orthonormalised(basis);
  MatrixXd product;
  for (int round = 0; round <= rounds; ++round) {
    product = whitening * FeatureJacobianGram(crops, whitening * basis, net);
    if (round < rounds) basis = Orthonormalised(product);
  }
  const MatrixXd small = basis.transpose() * product;
  Eigen::SelfAdjointEigenSolver<MatrixXd> eigen(0.5 *
                                                (small + small.transpose()));
  // Eigen sorts ascending: reverse the columns.
  return basis * eigen.eigenvectors().rowwise().reverse();
}

}  // namespace

std::vector<ImageRGB> SamplePhotoCrops(const std::vector<cv::Mat>& photos,
                                       int crop, int count, uint32_t seed) {
  std::vector<const cv::Mat*> usable;
  for (const cv::Mat& p : photos) {
    if (p.type() != CV_32FC3)
      Fail("SamplePhotoCrops: expected float RGB photos (CV_32FC3), got " +
           cv::typeToString(p.type()));
    if (p.rows >= crop && p.cols >= crop) usable.push_back(&p);
  }
  if (usable.empty())
    Fail("no photo is at least " + std::to_string(crop) + " pixels a side");
  std::mt19937 rng(seed);
  std::vector<ImageRGB> crops;
  crops.reserve(count);
  for (int k = 0; k < count; ++k) {
    const cv::Mat& photo = *usable[rng() % usable.size()];
    const int x0 = int(rng() % uint32_t(photo.cols - crop + 1));
    const int y0 = int(rng() % uint32_t(photo.rows - crop + 1));
    ImageRGB image(crop, crop);
    for (int y = 0; y < crop; ++y) {
      const float* row = photo.ptr<float>(y0 + y) + 3 * x0;
      std::copy(row, row + 3 * crop, image.At(0, y));
    }
    crops.push_back(std::move(image));
  }
  return crops;
}

void BlurCropsRandomly(std::vector<ImageRGB>* crops, double max_sigma,
                       uint32_t seed) {
  if (!(max_sigma >= 0) || max_sigma > 64)
    Fail("make_decoder: the calibration blur must be in [0, 64] pixels");
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> sigma_of(0.0, max_sigma);
  for (ImageRGB& crop : *crops) {
    const double sigma = sigma_of(rng);
    if (sigma < 0.05) continue;
    cv::Mat view(crop.height, crop.width, CV_32FC3, crop.data.data());
    cv::GaussianBlur(view, view, cv::Size(0, 0), sigma, sigma,
                     cv::BORDER_REFLECT101);
  }
}

std::unique_ptr<FeatureNet> CalibrateFeatureDecoder(
    const std::vector<cv::Mat>& photos,
    const FeatureCalibrationOptions& options,
    FeatureCalibrationReport* report) {
  const auto start = std::chrono::steady_clock::now();
  const FeatureDecoderConfig& config = options.config;
  if (config.num_bits > config.channels)
    Fail("make_decoder: " + std::to_string(config.num_bits) +
         " bits need at least as many channels (got " +
         std::to_string(config.channels) + ")");
  if (options.feature_crops <= config.channels)
    Fail("make_decoder: " + std::to_string(options.feature_crops) +
         " feature crops cannot estimate a " + std::to_string(config.channels) +
         "-channel covariance (need more crops than channels)");
  if (options.crop < config.pool)
    Fail("make_decoder: crop smaller than the pooling");
  if (options.steerable_subspace != 0 &&
      (options.steerable_subspace < config.num_bits ||
       options.steerable_subspace > config.channels))
    Fail(
        "make_decoder: the steerable subspace must hold between num_bits "
        "and channels directions");
  // The crops the statistics are taken over, render-like when asked.
  const auto calibration_crops = [&](int count, uint32_t seed) {
    std::vector<ImageRGB> crops =
        SamplePhotoCrops(photos, options.crop, count, seed);
    if (options.calibration_blur > 0)
      BlurCropsRandomly(&crops, options.calibration_blur, seed + 1000);
    return crops;
  };
  auto net = std::make_unique<FeatureNet>(config, options.seed);
  StandardiseConvolution(
      calibration_crops(options.normalisation_crops, options.seed + 1),
      net.get());
  const MatrixXd features = PooledFeatures(
      calibration_crops(options.feature_crops, options.seed + 2), net.get());
  const VectorXd mean = features.colwise().mean();
  const MatrixXd centred = features.rowwise() - mean.transpose();
  const MatrixXd covariance =
      centred.transpose() * centred / double(features.rows() - 1);
  Eigen::SelfAdjointEigenSolver<MatrixXd> eigen(covariance);
  VectorXd values = eigen.eigenvalues();
  const double floor = options.whiten_floor * values.mean();
  int floored = 0;
  for (int i = 0; i < values.size(); ++i)
    if (values(i) < floor) values(i) = floor, ++floored;
  const MatrixXd whitening = eigen.eigenvectors() *
                             values.cwiseInverse().cwiseSqrt().asDiagonal() *
                             eigen.eigenvectors().transpose();
  std::mt19937 rng(options.seed + 3);
  MatrixXd rows = RandomOrthogonalRows(config.num_bits, config.channels, &rng);
  if (options.steerable_subspace > 0) {
    // Random orthonormal rows inside the most steerable subspace instead of
    // all of whitened space.
    const int k = options.steerable_subspace;
    std::mt19937 subspace_rng(options.seed + 4);
    const MatrixXd subspace = SteerableSubspace(
        SamplePhotoCrops(photos, options.crop, options.steering_crops,
                         options.seed + 5),
        whitening, k, 2, net.get(), &subspace_rng);
    rows =
        RandomOrthogonalRows(config.num_bits, k, &rng) * subspace.transpose();
  }
  const MatrixXd projection = options.logit_scale * rows * whitening;
  const VectorXd bias = -projection * mean;
  for (int o = 0; o < config.num_bits; ++o) {
    for (int c = 0; c < config.channels; ++c)
      net->linear.weight.value[size_t(o) * config.channels + c] =
          float(projection(o, c));
    net->linear.bias.value[o] = float(bias(o));
  }
  for (float v : net->linear.weight.value)
    if (!std::isfinite(v))
      Fail("make_decoder: whitening produced NaN/Inf (raise --whiten_floor)");
  if (report) {
    int used = 0;
    for (const cv::Mat& p : photos)
      used += p.rows >= options.crop && p.cols >= options.crop;
    report->photos_used = used;
    report->max_eigenvalue = eigen.eigenvalues().maxCoeff();
    report->min_eigenvalue = eigen.eigenvalues().minCoeff();
    report->floored_eigenvalues = floored;
    report->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count();
  }
  return net;
}

DecoderBalance MeasureBalance(BitDecoder& decoder,
                              const std::vector<ImageRGB>& images,
                              const Bits& claimed, double present_p) {
  const int bits = decoder.NumBits();
  if (int(claimed.size()) != bits)
    Fail("MeasureBalance: claimed message of " +
         std::to_string(claimed.size()) + " bits for a " +
         std::to_string(bits) + "-bit decoder");
  DecoderBalance balance;
  balance.images = int(images.size());
  if (images.empty()) return balance;
  MatrixXd logits(images.size(), bits);
  int64_t ones = 0;
  balance.min_bit_errors = bits;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::vector<float> z = decoder.Logits(images[i]);
    int errors = 0;
    Bits read(bits);
    for (int b = 0; b < bits; ++b) {
      logits(i, b) = z[b];
      const bool one = z[b] > 0;
      read[b] = one;
      ones += one;
      errors += one != bool(claimed[b]);
    }
    balance.image_bits.push_back(std::move(read));
    balance.min_bit_errors = std::min(balance.min_bit_errors, errors);
    if (BinomialTailPValue(bits - errors, bits) <= present_p)
      ++balance.false_positives;
  }
  balance.ones_fraction = double(ones) / double(images.size() * bits);
  for (int b = 0; b < bits; ++b) {
    const double mean = logits.col(b).mean();
    balance.bit_mean.push_back(mean);
    balance.bit_std.push_back(std::sqrt(
        (logits.col(b).array() - mean).square().sum() / double(images.size())));
  }
  for (int b = 0; b < bits; ++b) {
    const double f = (logits.col(b).array() > 0).cast<double>().mean();
    balance.max_bit_ones = std::max(balance.max_bit_ones, f);
    balance.min_bit_ones = std::min(balance.min_bit_ones, f);
  }
  if (images.size() > 1 && bits > 1) {
    const MatrixXd centred = logits.rowwise() - logits.colwise().mean();
    const MatrixXd cov = centred.transpose() * centred;
    const VectorXd sd = cov.diagonal().cwiseSqrt();
    double sum = 0;
    for (int a = 0; a < bits; ++a)
      for (int b = 0; b < bits; ++b)
        if (a != b && sd(a) > 0 && sd(b) > 0)
          sum += std::abs(cov(a, b) / (sd(a) * sd(b)));
    balance.mean_abs_correlation = sum / double(bits * (bits - 1));
  }
  return balance;
}

SteerResult SteerPixels(BitDecoder& decoder, const ImageRGB& image,
                        const Bits& target, int max_steps, double lr,
                        double margin) {
  const int bits = decoder.NumBits();
  const std::vector<float> signs = BitSigns(target);
  const size_t n = image.data.size();
  std::vector<double> delta(n, 0.0), m(n, 0.0), v(n, 0.0);
  ImageRGB x = image, grad;
  std::vector<float> dlogits(bits);
  SteerResult result;
  for (int step = 1; step <= max_steps; ++step) {
    const std::vector<float> z = decoder.Logits(x);
    float worst = z[0] * signs[0];
    for (int b = 0; b < bits; ++b) {
      worst = std::min(worst, z[b] * signs[b]);
      // d/dz of mean BCE = (sigmoid(z) - t) / L.
      const double t = target[b] ? 1.0 : 0.0;
      dlogits[b] = float((1.0 / (1.0 + std::exp(-double(z[b]))) - t) / bits);
    }
    result.steps = step - 1;
    if (worst >= margin) break;
    decoder.InputGradient(x, dlogits, &grad);
    const double b1 = 0.9, b2 = 0.999;
    const double c1 = 1 - std::pow(b1, step), c2 = 1 - std::pow(b2, step);
    for (size_t i = 0; i < n; ++i) {
      m[i] = b1 * m[i] + (1 - b1) * grad.data[i];
      v[i] = b2 * v[i] + (1 - b2) * double(grad.data[i]) * grad.data[i];
      delta[i] -= lr * (m[i] / c1) / (std::sqrt(v[i] / c2) + 1e-8);
      x.data[i] = float(std::clamp(image.data[i] + delta[i], 0.0, 1.0));
    }
    result.steps = step;
  }
  const std::vector<float> z = decoder.Logits(x);
  double mse = 0;
  for (size_t i = 0; i < n; ++i) {
    const double d = double(x.data[i]) - image.data[i];
    mse += d * d;
  }
  mse = std::max(mse / double(n), 1e-12);
  result.psnr = 10.0 * std::log10(1.0 / mse);
  for (int b = 0; b < bits; ++b) result.bit_errors += (z[b] > 0) != target[b];
  result.image = std::move(x);
  return result;
}

}  // namespace watergs
