// L1, SSIM and PSNR with analytic gradients (see loss.h for conventions).
#include "gaussian/loss.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "gaussian/util/error.h"

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

// Per-thread scratch for BlurStrip: padded input rows, a ring of the last
// kSsimWindow horizontally blurred rows, and one output row, per plane.
template <typename T>
struct StripScratch {
  std::vector<T> padded, ring, out;
};

template <typename T>
StripScratch<T>& ThreadScratch() {
  thread_local StripScratch<T> scratch;
  return scratch;
}

// Rows [y0, y1) of the zero-padded 2-D blur of `count` planes of
// height x len values. fill(r, padded, padded_len, pad) writes the input
// rows r of every plane (plane p at padded + p * padded_len + pad);
// emit(y, out) receives the blurred rows (plane p at out + p * len). Rows are
// blurred horizontally once into a ring of the last 11, so the planes never
// leave the cache.
template <typename T, typename Fill, typename Emit>
void BlurStrip(int count, int height, int len, int stride, int y0, int y1,
               const std::array<T, kSsimWindow>& g, Fill&& fill, Emit&& emit) {
  const int pad = kRadius * stride;
  const int padded_len = len + 2 * pad;
  StripScratch<T>& s = ThreadScratch<T>();
  s.padded.assign(static_cast<size_t>(count) * padded_len, T(0));
  s.ring.resize(static_cast<size_t>(count) * kSsimWindow * len);
  s.out.resize(static_cast<size_t>(count) * len);
  auto ring_row = [&](int p, int r) {
    return s.ring.data() +
           (static_cast<size_t>(p) * kSsimWindow + (r % kSsimWindow)) * len;
  };
  auto blur_input_row = [&](int r) {
    fill(r, s.padded.data(), padded_len, pad);
    for (int p = 0; p < count; ++p) {
      BlurPaddedRow(s.padded.data() + static_cast<size_t>(p) * padded_len,
                    ring_row(p, r), len, stride, g);
    }
  };
  for (int r = std::max(0, y0 - kRadius); r < std::min(height, y0 + kRadius);
       ++r) {
    blur_input_row(r);
  }
  for (int y = y0; y < y1; ++y) {
    if (y + kRadius < height) blur_input_row(y + kRadius);
    for (int p = 0; p < count; ++p) {
      T* __restrict out = s.out.data() + static_cast<size_t>(p) * len;
      std::fill(out, out + len, T(0));
      for (int k = 0; k < kSsimWindow; ++k) {
        const int r = y + k - kRadius;
        if (r < 0 || r >= height) continue;
        const T gk = g[k];
        const T* __restrict src = ring_row(p, r);
#pragma omp simd
        for (int i = 0; i < len; ++i) out[i] += gk * src[i];
      }
    }
    emit(y, s.out.data());
  }
}

// Runs body(y0, y1) over contiguous row strips, one per thread.
template <typename Body>
void ForEachStrip(int height, bool parallel, Body&& body) {
#pragma omp parallel if (parallel)
  {
#ifdef _OPENMP
    const int threads = omp_get_num_threads(), t = omp_get_thread_num();
#else
    const int threads = 1, t = 0;
#endif
    const int y0 = static_cast<int>(int64_t(height) * t / threads);
    const int y1 = static_cast<int>(int64_t(height) * (t + 1) / threads);
    if (y1 > y0) body(y0, y1);
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
  const bool parallel = plane >= kParallelMinValues;
  thread_local std::vector<T> adjoint;  // 3 planes: dS/dmu_x, dS/dE[x^2],
                                        // dS/dE[xy], scaled by 1 / count
  thread_local std::vector<double> row_sums;
  row_sums.assign(height, 0.0);
  if (grad_x) adjoint.resize(3 * plane);
  // Lambdas run on other threads must not name the thread_local vectors.
  T* adj = adjoint.data();
  double* sums = row_sums.data();
  const T c1 = static_cast<T>(kC1), c2 = static_cast<T>(kC2);
  const T inv_count = static_cast<T>(1.0 / static_cast<double>(plane));

  // Padded rows of x, y, x^2, y^2, xy.
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
  // The SSIM map of a row from its local moments, and its adjoints:
  // S = A1 A2 / (B1 B2) as a function of mu_x, E[x^2], E[xy].
  auto ssim_row = [&](int row, const T* moments) {
    const T* mx = moments;
    const T* my = mx + len;
    const T* exx = my + len;
    const T* eyy = exx + len;
    const T* exy = eyy + len;
    const size_t base = static_cast<size_t>(row) * len;
    // Kept free of the double sum and of branches so that it vectorises.
    thread_local std::vector<T> map;
    map.resize(len);
    T* __restrict out = map.data();
#pragma omp simd
    for (int i = 0; i < len; ++i) {
      const T a1 = 2 * mx[i] * my[i] + c1;
      const T a2 = 2 * (exy[i] - mx[i] * my[i]) + c2;
      const T b1 = mx[i] * mx[i] + my[i] * my[i] + c1;
      const T b2 = (exx[i] - mx[i] * mx[i]) + (eyy[i] - my[i] * my[i]) + c2;
      out[i] = (a1 * a2) / (b1 * b2);
    }
    if (grad_x) {
      T* __restrict d_mu = adj + base;
      T* __restrict d_xx = adj + plane + base;
      T* __restrict d_xy = adj + 2 * plane + base;
#pragma omp simd
      for (int i = 0; i < len; ++i) {
        const T a1 = 2 * mx[i] * my[i] + c1;
        const T a2 = 2 * (exy[i] - mx[i] * my[i]) + c2;
        const T b1 = mx[i] * mx[i] + my[i] * my[i] + c1;
        const T b2 = (exx[i] - mx[i] * mx[i]) + (eyy[i] - my[i] * my[i]) + c2;
        const T ssim = out[i];
        d_mu[i] =
            inv_count * ssim *
            (2 * my[i] / a1 - 2 * my[i] / a2 - 2 * mx[i] / b1 + 2 * mx[i] / b2);
        d_xx[i] = -inv_count * ssim / b2;
        d_xy[i] = inv_count * 2 * a1 / (b1 * b2);
      }
    }
    double row_sum = 0;
    for (int i = 0; i < len; ++i) row_sum += out[i];
    sums[row] = row_sum;
  };
  ForEachStrip(height, parallel, [&](int y0, int y1) {
    BlurStrip<T>(5, height, len, channels, y0, y1, g, fill_moments, ssim_row);
  });
  double sum = 0;
  for (double r : row_sums) sum += r;
  if (!grad_x) return sum / static_cast<double>(plane);

  // The window is symmetric, so the adjoint of the zero-padded correlation
  // is the same zero-padded correlation.
  auto fill_adjoint = [&](int row, T* padded, int padded_len, int pad) {
    for (int p = 0; p < 3; ++p) {
      std::copy_n(adj + p * plane + static_cast<size_t>(row) * len, len,
                  padded + p * padded_len + pad);
    }
  };
  auto gradient_row = [&](int row, const T* blurred) {
    const size_t base = static_cast<size_t>(row) * len;
    const T* b_mu = blurred;
    const T* b_xx = b_mu + len;
    const T* b_xy = b_xx + len;
    for (int i = 0; i < len; ++i) {
      grad_x[base + i] =
          b_mu[i] + 2 * x[base + i] * b_xx[i] + y[base + i] * b_xy[i];
    }
  };
  ForEachStrip(height, parallel, [&](int y0, int y1) {
    BlurStrip<T>(3, height, len, channels, y0, y1, g, fill_adjoint,
                 gradient_row);
  });
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

void CheckImageSize(int width, int height, const ImageRGB& image) {
  if (image.width != width || image.height != height ||
      image.data.size() != 3 * size_t(width) * size_t(height)) {
    Fail("loss: image sizes differ (" + std::to_string(width) + "x" +
         std::to_string(height) + " vs " + std::to_string(image.width) + "x" +
         std::to_string(image.height) + ")");
  }
}

namespace {

void CheckSameSize(const ImageRGB& a, const ImageRGB& b) {
  if (a.data.size() != 3 * size_t(a.width) * size_t(a.height)) {
    Fail("loss: image of " + std::to_string(a.width) + "x" +
         std::to_string(a.height) + " with " + std::to_string(a.data.size()) +
         " values");
  }
  CheckImageSize(a.width, a.height, b);
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
