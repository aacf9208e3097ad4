// Multi-scale SSIM (see image_quality.h).
#include "watermark/image_quality.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr int kWindow = 11;
constexpr double kSigma = 1.5;
constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;

// One channel as a height x width plane of doubles.
struct Plane {
  int width = 0, height = 0;
  std::vector<double> v;
  double& at(int x, int y) { return v[size_t(y) * width + x]; }
  double at(int x, int y) const { return v[size_t(y) * width + x]; }
};

std::vector<double> GaussianWindow() {
  std::vector<double> w(kWindow);
  double total = 0;
  for (int k = 0; k < kWindow; ++k) {
    const double d = k - kWindow / 2;
    total += w[k] = std::exp(-d * d / (2 * kSigma * kSigma));
  }
  for (double& x : w) x /= total;
  return w;
}

// Separable "valid" Gaussian filter: (W-10) x (H-10).
Plane Filter(const Plane& in, const std::vector<double>& w) {
  Plane rows{in.width - kWindow + 1, in.height, {}};
  rows.v.assign(size_t(rows.width) * rows.height, 0.0);
  for (int y = 0; y < rows.height; ++y) {
    for (int x = 0; x < rows.width; ++x) {
      double sum = 0;
      for (int k = 0; k < kWindow; ++k) sum += w[k] * in.at(x + k, y);
      rows.at(x, y) = sum;
    }
  }
  Plane out{rows.width, in.height - kWindow + 1, {}};
  out.v.assign(size_t(out.width) * out.height, 0.0);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      double sum = 0;
      for (int k = 0; k < kWindow; ++k) sum += w[k] * rows.at(x, y + k);
      out.at(x, y) = sum;
    }
  }
  return out;
}

Plane Product(const Plane& a, const Plane& b) {
  Plane out = a;
  for (size_t i = 0; i < out.v.size(); ++i) out.v[i] *= b.v[i];
  return out;
}

// Mean contrast-structure and mean SSIM of one scale.
void ScaleTerms(const Plane& x, const Plane& y, const std::vector<double>& w,
                double* mean_cs, double* mean_ssim) {
  const Plane mx = Filter(x, w), my = Filter(y, w);
  const Plane xx = Filter(Product(x, x), w), yy = Filter(Product(y, y), w);
  const Plane xy = Filter(Product(x, y), w);
  double cs_sum = 0, ssim_sum = 0;
  for (size_t i = 0; i < mx.v.size(); ++i) {
    const double vx = xx.v[i] - mx.v[i] * mx.v[i];
    const double vy = yy.v[i] - my.v[i] * my.v[i];
    const double cov = xy.v[i] - mx.v[i] * my.v[i];
    const double cs = (2 * cov + kC2) / (vx + vy + kC2);
    const double l = (2 * mx.v[i] * my.v[i] + kC1) /
                     (mx.v[i] * mx.v[i] + my.v[i] * my.v[i] + kC1);
    cs_sum += cs;
    ssim_sum += l * cs;
  }
  *mean_cs = cs_sum / double(mx.v.size());
  *mean_ssim = ssim_sum / double(mx.v.size());
}

Plane Downsample(const Plane& in) {
  Plane out{in.width / 2, in.height / 2, {}};
  out.v.resize(size_t(out.width) * out.height);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      out.at(x, y) =
          0.25 * (in.at(2 * x, 2 * y) + in.at(2 * x + 1, 2 * y) +
                  in.at(2 * x, 2 * y + 1) + in.at(2 * x + 1, 2 * y + 1));
    }
  }
  return out;
}

Plane Channel(const ImageRGB& image, int c) {
  Plane p{image.width, image.height, {}};
  p.v.resize(size_t(image.width) * image.height);
  for (size_t i = 0; i < p.v.size(); ++i) {
    p.v[i] = std::clamp(image.data[i * 3 + c], 0.f, 1.f);
  }
  return p;
}

}  // namespace

int MsSsimScales(int width, int height) {
  int side = std::min(width, height), scales = 0;
  while (scales < 5 && side >= kWindow) {
    ++scales;
    side /= 2;
  }
  return scales;
}

MsSsimResult MsSsim(const ImageRGB& a, const ImageRGB& b) {
  if (a.width != b.width || a.height != b.height) {
    Fail("MS-SSIM: images of different sizes (" + std::to_string(a.width) +
         "x" + std::to_string(a.height) + " and " + std::to_string(b.width) +
         "x" + std::to_string(b.height) + ")");
  }
  MsSsimResult result;
  result.scales = MsSsimScales(a.width, a.height);
  if (result.scales == 0) {
    result.value = std::numeric_limits<double>::quiet_NaN();
    return result;
  }
  // Five scales use the published weights as they are (they sum to 1.0001);
  // fewer scales renormalise theirs to sum 1.
  double weight_sum = 1;
  if (result.scales < 5) {
    weight_sum = 0;
    for (int j = 0; j < result.scales; ++j) weight_sum += kMsSsimWeights[j];
  }
  const std::vector<double> window = GaussianWindow();
  double channel_sum = 0;
  for (int c = 0; c < 3; ++c) {
    Plane x = Channel(a, c), y = Channel(b, c);
    double product = 1;
    for (int j = 0; j < result.scales; ++j) {
      double cs = 0, ssim = 0;
      ScaleTerms(x, y, window, &cs, &ssim);
      const bool last = j + 1 == result.scales;
      product *= std::pow(std::max(last ? ssim : cs, 0.0),
                          kMsSsimWeights[j] / weight_sum);
      if (!last) {
        x = Downsample(x);
        y = Downsample(y);
      }
    }
    channel_sum += product;
  }
  result.value = channel_sum / 3;
  return result;
}

}  // namespace watergs
