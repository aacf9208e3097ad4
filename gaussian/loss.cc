// L1, SSIM and PSNR with analytic gradients (see loss.h for conventions).
#include "gaussian/loss.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gaussian/error.h"

namespace watergs {
namespace {

constexpr int kRadius = kSsimWindow / 2;
constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;
// Images with fewer values than this are filtered on one thread.
constexpr size_t kParallelMinValues = size_t(1) << 15;

// The 1-D window; its outer product is Inria's normalised 2-D window.
template <typename T>
std::array<T, kSsimWindow> GaussianWindow() {
  std::array<double, kSsimWindow> g;
  double sum = 0;
  for (int k = 0; k < kSsimWindow; ++k) {
    const double d = k - kRadius;
    g[k] = std::exp(-d * d / (2 * kSsimSigma * kSsimSigma));
    sum += g[k];
  }
  std::array<T, kSsimWindow> out;
  for (int k = 0; k < kSsimWindow; ++k) out[k] = static_cast<T>(g[k] / sum);
  return out;
}

// out[i] = sum_k g[k] * padded[i + k * stride], i < len; padded holds
// kRadius * stride zeros on each side of the row.
template <typename T>
void BlurPaddedRow(const T* padded, T* __restrict out, int len, int stride,
                   const std::array<T, kSsimWindow>& g) {
  std::fill(out, out + len, T(0));
  for (int k = 0; k < kSsimWindow; ++k) {
    const T gk = g[k];
    const T* __restrict src = padded + k * stride;
#pragma omp simd
    for (int i = 0; i < len; ++i) out[i] += gk * src[i];
  }
}

// Row y of the vertical zero-padded blur of `planes` images of
// height x len values each: out[p][y] = sum_k g[k] in[p][y + k - r].
template <typename T>
void BlurColumnsRow(const T* in, T* __restrict out, int height, int len, int y,
                    const std::array<T, kSsimWindow>& g) {
  std::fill(out, out + len, T(0));
  for (int k = 0; k < kSsimWindow; ++k) {
    const int yy = y + k - kRadius;
    if (yy < 0 || yy >= height) continue;
    const T gk = g[k];
    const T* __restrict src = in + static_cast<size_t>(yy) * len;
#pragma omp simd
    for (int i = 0; i < len; ++i) out[i] += gk * src[i];
  }
}

// Scratch planes reused across calls (one set per calling thread).
template <typename T>
struct SsimScratch {
  std::vector<T> horizontal;  // 5 planes after the horizontal pass
  std::vector<T> moments;     // 5 planes: mu_x, mu_y, E[x^2], E[y^2], E[xy]
  std::vector<T> adjoint;     // 3 planes: dS/dmu_x, dS/dE[x^2], dS/dE[xy]
  std::vector<double> row_sums;
};

template <typename T>
SsimScratch<T>& Scratch() {
  thread_local SsimScratch<T> scratch;
  return scratch;
}

// Horizontal then vertical blur of `count` planes of height x len, the
// horizontal input produced row by row by fill(y, padded_rows).
template <typename T, typename Fill>
void BlurPlanes(int count, int height, int len, int stride, Fill fill,
                T* horizontal, T* out, const std::array<T, kSsimWindow>& g) {
  const size_t plane = static_cast<size_t>(height) * len;
  const int pad = kRadius * stride;
  // Small images are not worth waking threads for.
  const bool parallel = plane >= kParallelMinValues;
#pragma omp parallel if (parallel)
  {
    std::vector<T> padded(static_cast<size_t>(count) * (len + 2 * pad), T(0));
#pragma omp for schedule(static)
    for (int y = 0; y < height; ++y) {
      fill(y, padded.data(), len + 2 * pad, pad);
      for (int p = 0; p < count; ++p) {
        BlurPaddedRow(padded.data() + p * (len + 2 * pad),
                      horizontal + p * plane + static_cast<size_t>(y) * len,
                      len, stride, g);
      }
    }
#pragma omp for schedule(static)
    for (int y = 0; y < height; ++y) {
      for (int p = 0; p < count; ++p) {
        BlurColumnsRow(horizontal + p * plane,
                       out + p * plane + static_cast<size_t>(y) * len, height,
                       len, y, g);
      }
    }
  }
}

}  // namespace

template <typename T>
double SsimInterleaved(const T* x, const T* y, int width, int height,
                       int channels, T* grad_x) {
  if (width <= 0 || height <= 0 || channels <= 0) return 1.0;
  const auto g = GaussianWindow<T>();
  const int len = width * channels;
  const size_t plane = static_cast<size_t>(height) * len;
  SsimScratch<T>& s = Scratch<T>();
  s.horizontal.resize(5 * plane);
  s.moments.resize(5 * plane);
  s.row_sums.assign(height, 0.0);

  // Padded rows of x, y, x^2, y^2, xy (zeros outside the image).
  auto fill_moments = [&](int row, T* padded, int padded_len, int pad) {
    const T* xr = x + static_cast<size_t>(row) * len;
    const T* yr = y + static_cast<size_t>(row) * len;
    T* px = padded + pad;
    T* py = px + padded_len;
    T* pxx = py + padded_len;
    T* pyy = pxx + padded_len;
    T* pxy = pyy + padded_len;
    for (int i = 0; i < len; ++i) {
      px[i] = xr[i];
      py[i] = yr[i];
      pxx[i] = xr[i] * xr[i];
      pyy[i] = yr[i] * yr[i];
      pxy[i] = xr[i] * yr[i];
    }
  };
  BlurPlanes<T>(5, height, len, channels, fill_moments, s.horizontal.data(),
                s.moments.data(), g);

  const T c1 = static_cast<T>(kC1), c2 = static_cast<T>(kC2);
  const T inv_count = static_cast<T>(1.0 / static_cast<double>(plane));
  if (grad_x) s.adjoint.resize(3 * plane);
  const T* mx = s.moments.data();
  const T* my = mx + plane;
  const T* exx = my + plane;
  const T* eyy = exx + plane;
  const T* exy = eyy + plane;
#pragma omp parallel for schedule(static) if (plane >= kParallelMinValues)
  for (int row = 0; row < height; ++row) {
    double row_sum = 0;
    for (size_t i = static_cast<size_t>(row) * len,
                end = static_cast<size_t>(row + 1) * len;
         i < end; ++i) {
      const T a1 = 2 * mx[i] * my[i] + c1;
      const T a2 = 2 * (exy[i] - mx[i] * my[i]) + c2;
      const T b1 = mx[i] * mx[i] + my[i] * my[i] + c1;
      const T b2 = (exx[i] - mx[i] * mx[i]) + (eyy[i] - my[i] * my[i]) + c2;
      const T ssim = (a1 * a2) / (b1 * b2);
      row_sum += ssim;
      if (!grad_x) continue;
      // S = A1 A2 / (B1 B2) as a function of mu_x, E[x^2], E[xy].
      const T d_mu = ssim * (2 * my[i] / a1 - 2 * my[i] / a2 - 2 * mx[i] / b1 +
                             2 * mx[i] / b2);
      s.adjoint[i] = inv_count * d_mu;
      s.adjoint[plane + i] = -inv_count * ssim / b2;
      s.adjoint[2 * plane + i] = inv_count * 2 * a1 / (b1 * b2);
    }
    s.row_sums[row] = row_sum;
  }
  double sum = 0;
  for (double r : s.row_sums) sum += r;
  if (!grad_x) return sum / static_cast<double>(plane);

  // The window is symmetric, so the adjoint of the zero-padded correlation
  // is the same zero-padded correlation.
  auto fill_adjoint = [&](int row, T* padded, int padded_len, int pad) {
    for (int p = 0; p < 3; ++p) {
      std::copy_n(s.adjoint.data() + p * plane + static_cast<size_t>(row) * len,
                  len, padded + p * padded_len + pad);
    }
  };
  // Reuse the moment planes 0..2 for the blurred adjoints.
  BlurPlanes<T>(3, height, len, channels, fill_adjoint, s.horizontal.data(),
                s.moments.data(), g);
  const T* b_mu = s.moments.data();
  const T* b_xx = b_mu + plane;
  const T* b_xy = b_xx + plane;
#pragma omp parallel for schedule(static) if (plane >= kParallelMinValues)
  for (int row = 0; row < height; ++row) {
    for (size_t i = static_cast<size_t>(row) * len,
                end = static_cast<size_t>(row + 1) * len;
         i < end; ++i) {
      grad_x[i] = b_mu[i] + 2 * x[i] * b_xx[i] + y[i] * b_xy[i];
    }
  }
  return sum / static_cast<double>(plane);
}

template <typename T>
double L1Interleaved(const T* x, const T* y, size_t count, T* grad_x) {
  if (count == 0) return 0.0;
  const T inv_count = static_cast<T>(1.0 / static_cast<double>(count));
  double sum = 0;
  for (size_t i = 0; i < count; ++i) {
    const T d = x[i] - y[i];
    sum += std::abs(d);
    if (grad_x) grad_x[i] = d > 0 ? inv_count : (d < 0 ? -inv_count : T(0));
  }
  return sum / static_cast<double>(count);
}

template double SsimInterleaved<float>(const float*, const float*, int, int,
                                       int, float*);
template double SsimInterleaved<double>(const double*, const double*, int, int,
                                        int, double*);
template double L1Interleaved<float>(const float*, const float*, size_t,
                                     float*);
template double L1Interleaved<double>(const double*, const double*, size_t,
                                      double*);

namespace {

void CheckSameSize(const ImageRGB& a, const ImageRGB& b) {
  if (a.width != b.width || a.height != b.height ||
      a.data.size() != b.data.size()) {
    Fail("loss: image sizes differ (" + std::to_string(a.width) + "x" +
         std::to_string(a.height) + " vs " + std::to_string(b.width) + "x" +
         std::to_string(b.height) + ")");
  }
}

void PrepareGrad(const ImageRGB& like, ImageRGB* grad) {
  grad->width = like.width;
  grad->height = like.height;
  grad->data.resize(like.data.size());
}

}  // namespace

double Ssim(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a) {
  CheckSameSize(a, b);
  if (grad_a) PrepareGrad(a, grad_a);
  return SsimInterleaved(a.data.data(), b.data.data(), a.width, a.height, 3,
                         grad_a ? grad_a->data.data() : nullptr);
}

double L1(const ImageRGB& a, const ImageRGB& b, ImageRGB* grad_a) {
  CheckSameSize(a, b);
  if (grad_a) PrepareGrad(a, grad_a);
  return L1Interleaved(a.data.data(), b.data.data(), a.data.size(),
                       grad_a ? grad_a->data.data() : nullptr);
}

double Psnr(const ImageRGB& rendered, const ImageRGB& truth) {
  CheckSameSize(rendered, truth);
  double sum = 0;
  for (size_t i = 0; i < rendered.data.size(); ++i) {
    const double d =
        std::clamp(rendered.data[i], 0.f, 1.f) - double(truth.data[i]);
    sum += d * d;
  }
  const double mse = sum / std::max<size_t>(rendered.data.size(), 1);
  if (mse <= 0) return std::numeric_limits<double>::infinity();
  return -10.0 * std::log10(mse);
}

LossTerms TrainingLoss::Evaluate(const ImageRGB& rendered,
                                 const ImageRGB& truth, ImageRGB* grad) {
  CheckSameSize(rendered, truth);
  LossTerms terms;
  if (!grad) {
    terms.l1 = L1(rendered, truth, nullptr);
    terms.ssim = Ssim(rendered, truth, nullptr);
  } else {
    PrepareGrad(rendered, grad);
    ssim_grad_.resize(rendered.data.size());
    terms.l1 = L1Interleaved(rendered.data.data(), truth.data.data(),
                             rendered.data.size(), grad->data.data());
    terms.ssim =
        SsimInterleaved(rendered.data.data(), truth.data.data(), rendered.width,
                        rendered.height, 3, ssim_grad_.data());
    const float w_l1 = static_cast<float>(1.0 - lambda_);
    const float w_ssim = static_cast<float>(-lambda_);
    float* g = grad->data.data();
    const float* gs = ssim_grad_.data();
    const size_t n = rendered.data.size();
    for (size_t i = 0; i < n; ++i) g[i] = w_l1 * g[i] + w_ssim * gs[i];
  }
  terms.total = (1.0 - lambda_) * terms.l1 + lambda_ * (1.0 - terms.ssim);
  return terms;
}

}  // namespace watergs
