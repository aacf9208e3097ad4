// NCHW float32 tensors for the neural-network module (CPU storage). A device
// twin (CUDA) mirrors the same shape fields with device memory.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace watergs {

struct Tensor {
  // Batch, channels, height, width.
  int n = 0, c = 0, h = 0, w = 0;
  // n * c * h * w values, NCHW row-major.
  std::vector<float> data;

  Tensor() = default;
  Tensor(int n_, int c_, int h_, int w_) { Resize(n_, c_, h_, w_); }
  // Sets the shape; keeps the allocation when it is large enough. Values are
  // left unspecified (zeroed only on growth).
  void Resize(int n_, int c_, int h_, int w_) {
    n = n_, c = c_, h = h_, w = w_;
    data.resize(size_t(n) * c * h * w);
  }
  // Same shape as `other`.
  void ResizeLike(const Tensor& other) {
    Resize(other.n, other.c, other.h, other.w);
  }
  size_t size() const { return data.size(); }
  size_t PlaneSize() const { return size_t(h) * w; }
  // Pointer to plane (b, ch): h * w values.
  float* Plane(int b, int ch) {
    return data.data() + (size_t(b) * c + ch) * h * w;
  }
  const float* Plane(int b, int ch) const {
    return data.data() + (size_t(b) * c + ch) * h * w;
  }
  void Fill(float value) { std::fill(data.begin(), data.end(), value); }
  bool SameShape(const Tensor& o) const {
    return n == o.n && c == o.c && h == o.h && w == o.w;
  }
};

}  // namespace watergs
