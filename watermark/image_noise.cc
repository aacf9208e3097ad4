// 2D noise layers (see image_noise.h).
#include "watermark/image_noise.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Bilinear sample positions along one axis, as cv::resize INTER_LINEAR
// (half-pixel centres, clamped at the borders).
struct Taps {
  std::vector<int> i0, i1;
  std::vector<float> w1;
};

Taps BilinearTaps(int in, int out) {
  Taps taps;
  const float scale = float(in) / float(out);
  for (int o = 0; o < out; ++o) {
    float s = std::clamp((o + 0.5f) * scale - 0.5f, 0.f, float(in - 1));
    const int a = std::min(int(s), in - 1);
    taps.i0.push_back(a);
    taps.i1.push_back(std::min(a + 1, in - 1));
    taps.w1.push_back(s - float(a));
  }
  return taps;
}

// Separable 1D convolution with clamp-to-edge borders along x (axis 0) or y.
void Blur1D(const float* in, float* out, int h, int w,
            const std::vector<float>& kernel, bool along_x, bool adjoint) {
  const int r = int(kernel.size()) / 2;
  if (adjoint) std::fill(out, out + size_t(h) * w, 0.f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float sum = 0.f;
      for (int k = -r; k <= r; ++k) {
        const int sx = along_x ? std::clamp(x + k, 0, w - 1) : x;
        const int sy = along_x ? y : std::clamp(y + k, 0, h - 1);
        if (adjoint)
          out[size_t(sy) * w + sx] += kernel[k + r] * in[size_t(y) * w + x];
        else
          sum += kernel[k + r] * in[size_t(sy) * w + sx];
      }
      if (!adjoint) out[size_t(y) * w + x] = sum;
    }
  }
}

}  // namespace

const char* NoiseName(NoiseKind kind) {
  switch (kind) {
    case NoiseKind::kIdentity:
      return "identity";
    case NoiseKind::kCrop:
      return "crop";
    case NoiseKind::kDropout:
      return "dropout";
    case NoiseKind::kResize:
      return "resize";
    case NoiseKind::kBlur:
      return "blur";
    case NoiseKind::kJpeg:
      return "jpeg";
  }
  return "?";
}

std::vector<NoiseKind> ParseNoiseList(const std::string& list) {
  std::vector<NoiseKind> kinds;
  std::stringstream stream(list);
  std::string item;
  while (std::getline(stream, item, ',')) {
    bool found = false;
    for (NoiseKind k :
         {NoiseKind::kIdentity, NoiseKind::kCrop, NoiseKind::kDropout,
          NoiseKind::kResize, NoiseKind::kBlur, NoiseKind::kJpeg}) {
      if (item == NoiseName(k)) {
        kinds.push_back(k);
        found = true;
      }
    }
    if (!found)
      Fail("--noise: unknown noise layer '" + item +
           "' (identity, crop, dropout, resize, blur, jpeg)");
  }
  if (kinds.empty()) Fail("--noise: empty list");
  return kinds;
}

void ImageNoise::Forward(NoiseKind kind, const Tensor& wm, const Tensor& cover,
                         Tensor* noised, std::mt19937* rng) {
  kind_ = kind;
  n_ = wm.n, h_ = wm.h, w_ = wm.w;
  const size_t hw = wm.PlaneSize();
  switch (kind) {
    case NoiseKind::kIdentity:
      *noised = wm;
      return;
    case NoiseKind::kCrop: {
      const int ch = std::max(1, int(std::lround(h_ * strengths_.crop_side)));
      const int cw = std::max(1, int(std::lround(w_ * strengths_.crop_side)));
      crop_y_ = std::uniform_int_distribution<int>(0, h_ - ch)(*rng);
      crop_x_ = std::uniform_int_distribution<int>(0, w_ - cw)(*rng);
      noised->Resize(n_, 3, ch, cw);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c)
          for (int y = 0; y < ch; ++y)
            std::copy_n(wm.Plane(b, c) + size_t(y + crop_y_) * w_ + crop_x_, cw,
                        noised->Plane(b, c) + size_t(y) * cw);
      return;
    }
    case NoiseKind::kDropout: {
      std::bernoulli_distribution keep(1.0 - strengths_.dropout);
      keep_.resize(size_t(n_) * hw);
      for (auto& k : keep_) k = keep(*rng);
      noised->ResizeLike(wm);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c)
          for (size_t i = 0; i < hw; ++i)
            noised->Plane(b, c)[i] =
                keep_[b * hw + i] ? wm.Plane(b, c)[i] : cover.Plane(b, c)[i];
      return;
    }
    case NoiseKind::kResize: {
      const float s = std::uniform_real_distribution<float>(
          strengths_.resize_min, 1.f)(*rng);
      const int oh = std::max(8, int(std::lround(h_ * s)));
      const int ow = std::max(8, int(std::lround(w_ * s)));
      const Taps ty = BilinearTaps(h_, oh), tx = BilinearTaps(w_, ow);
      noised->Resize(n_, 3, oh, ow);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c) {
          const float* in = wm.Plane(b, c);
          float* out = noised->Plane(b, c);
          for (int y = 0; y < oh; ++y)
            for (int x = 0; x < ow; ++x) {
              const float* r0 = in + size_t(ty.i0[y]) * w_;
              const float* r1 = in + size_t(ty.i1[y]) * w_;
              const float top =
                  r0[tx.i0[x]] + tx.w1[x] * (r0[tx.i1[x]] - r0[tx.i0[x]]);
              const float bot =
                  r1[tx.i0[x]] + tx.w1[x] * (r1[tx.i1[x]] - r1[tx.i0[x]]);
              out[size_t(y) * ow + x] = top + ty.w1[y] * (bot - top);
            }
        }
      return;
    }
    case NoiseKind::kBlur: {
      const int r = std::max(1, int(std::ceil(2 * strengths_.blur_sigma)));
      kernel_.assign(2 * r + 1, 0.f);
      float total = 0.f;
      for (int k = -r; k <= r; ++k)
        total += kernel_[k + r] = std::exp(
            -0.5f * k * k / (strengths_.blur_sigma * strengths_.blur_sigma));
      for (float& k : kernel_) k /= total;
      noised->ResizeLike(wm);
      std::vector<float> tmp(hw);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c) {
          Blur1D(wm.Plane(b, c), tmp.data(), h_, w_, kernel_, true, false);
          Blur1D(tmp.data(), noised->Plane(b, c), h_, w_, kernel_, false,
                 false);
        }
      return;
    }
    case NoiseKind::kJpeg: {
      noised->ResizeLike(wm);
      std::vector<uchar> bytes;
      for (int b = 0; b < n_; ++b) {
        cv::Mat image(h_, w_, CV_8UC3);
        for (int y = 0; y < h_; ++y)
          for (int x = 0; x < w_; ++x)
            for (int c = 0; c < 3; ++c) {
              const float v =
                  (wm.Plane(b, c)[size_t(y) * w_ + x] + 1.f) * 127.5f;
              // OpenCV stores BGR.
              image.at<cv::Vec3b>(y, x)[2 - c] = cv::saturate_cast<uchar>(
                  std::lround(std::clamp(v, 0.f, 255.f)));
            }
        cv::imencode(".jpg", image, bytes,
                     {cv::IMWRITE_JPEG_QUALITY, strengths_.jpeg_quality});
        const cv::Mat decoded = cv::imdecode(bytes, cv::IMREAD_COLOR);
        for (int y = 0; y < h_; ++y)
          for (int x = 0; x < w_; ++x)
            for (int c = 0; c < 3; ++c)
              noised->Plane(b, c)[size_t(y) * w_ + x] =
                  decoded.at<cv::Vec3b>(y, x)[2 - c] / 127.5f - 1.f;
      }
      return;
    }
  }
}

void ImageNoise::Backward(const Tensor& dn, Tensor* dwm) const {
  dwm->Resize(n_, 3, h_, w_);
  const size_t hw = dwm->PlaneSize();
  switch (kind_) {
    case NoiseKind::kIdentity:
    case NoiseKind::kJpeg:  // straight-through estimator
      std::copy(dn.data.begin(), dn.data.end(), dwm->data.begin());
      return;
    case NoiseKind::kCrop:
      dwm->Fill(0.f);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c)
          for (int y = 0; y < dn.h; ++y)
            std::copy_n(dn.Plane(b, c) + size_t(y) * dn.w, dn.w,
                        dwm->Plane(b, c) + size_t(y + crop_y_) * w_ + crop_x_);
      return;
    case NoiseKind::kDropout:
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c)
          for (size_t i = 0; i < hw; ++i)
            dwm->Plane(b, c)[i] = keep_[b * hw + i] ? dn.Plane(b, c)[i] : 0.f;
      return;
    case NoiseKind::kResize: {
      const Taps ty = BilinearTaps(h_, dn.h), tx = BilinearTaps(w_, dn.w);
      dwm->Fill(0.f);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c) {
          const float* g = dn.Plane(b, c);
          float* out = dwm->Plane(b, c);
          for (int y = 0; y < dn.h; ++y)
            for (int x = 0; x < dn.w; ++x) {
              const float v = g[size_t(y) * dn.w + x];
              const float wy1 = ty.w1[y], wx1 = tx.w1[x];
              out[size_t(ty.i0[y]) * w_ + tx.i0[x]] +=
                  (1 - wy1) * (1 - wx1) * v;
              out[size_t(ty.i0[y]) * w_ + tx.i1[x]] += (1 - wy1) * wx1 * v;
              out[size_t(ty.i1[y]) * w_ + tx.i0[x]] += wy1 * (1 - wx1) * v;
              out[size_t(ty.i1[y]) * w_ + tx.i1[x]] += wy1 * wx1 * v;
            }
        }
      return;
    }
    case NoiseKind::kBlur: {
      std::vector<float> tmp(hw);
      for (int b = 0; b < n_; ++b)
        for (int c = 0; c < 3; ++c) {
          Blur1D(dn.Plane(b, c), tmp.data(), h_, w_, kernel_, false, true);
          Blur1D(tmp.data(), dwm->Plane(b, c), h_, w_, kernel_, true, true);
        }
      return;
    }
  }
}

}  // namespace watergs
