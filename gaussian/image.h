// A float RGB image, the rasterizer's output and the losses' input.
#pragma once

#include <cstddef>
#include <vector>

namespace watergs {

// Height x width x 3 floats, row-major, rgb interleaved, nominally in [0, 1].
struct ImageRGB {
  // Size in pixels.
  int width = 0;
  int height = 0;
  // width * height * 3 values.
  std::vector<float> data;

  ImageRGB() = default;
  ImageRGB(int w, int h) : width(w), height(h), data(size_t(w) * h * 3, 0.f) {}
  float* At(int x, int y) { return &data[(size_t(y) * width + x) * 3]; }
  const float* At(int x, int y) const {
    return &data[(size_t(y) * width + x) * 3];
  }
};

}  // namespace watergs
