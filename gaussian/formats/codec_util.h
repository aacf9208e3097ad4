// Small helpers shared by the readers and writers of the quantised 3DGS
// formats (spz_io, splat_io, compressed_ply_io): little-endian loads and
// stores, unit-interval quantisation, quaternion normalisation.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

namespace watergs::codec {

// SH band-0 constant, 1 / (2 sqrt(pi)).
constexpr double kShC0 = 0.28209479177387814;

inline uint32_t LoadU32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 |
         uint32_t(p[3]) << 24;
}

inline float LoadF32(const uint8_t* p) {
  const uint32_t bits = LoadU32(p);
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

inline void AppendU32(uint32_t v, std::string* out) {
  for (int k = 0; k < 4; ++k) out->push_back(char((v >> (8 * k)) & 0xff));
}

inline void AppendF32(float f, std::string* out) {
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  AppendU32(bits, out);
}

// round(v) clamped to [0, max]; NaN gives 0.
inline uint32_t RoundClamp(double v, uint32_t max) {
  if (!(v > 0)) return 0;
  if (v >= max) return max;
  return uint32_t(std::lround(v));
}

// floor(v) clamped to [0, max] (what a JavaScript Uint8Array store of a
// clamped value does); NaN gives 0.
inline uint32_t TruncClamp(double v, uint32_t max) {
  if (!(v > 0)) return 0;
  if (v >= max) return max;
  return uint32_t(v);
}

// q / |q| (w, x, y, z order kept); the identity if |q| is 0 or not finite.
inline std::array<double, 4> Normalized(const float* q) {
  const double n = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] +
                             double(q[2]) * q[2] + double(q[3]) * q[3]);
  if (!(n > 0) || !std::isfinite(n)) return {1, 0, 0, 0};
  return {q[0] / n, q[1] / n, q[2] / n, q[3] / n};
}

}  // namespace watergs::codec
