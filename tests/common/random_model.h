// Test helper shared by the module test executables: random Gaussians.
#pragma once

#include <cstdint>
#include <random>

#include "gaussian/gaussian_model.h"

namespace watergs {

// How RandomModel spreads each attribute: uniform u in [-1, 1] times these.
struct RandomModelRanges {
  float means = 1;                // means in [-means, means]^3
  float log_scale_spread = 0.5f;  // log-scales -3 +- this
  float opacity = 3;              // opacity logits
  float sh_rest = 0.2f;           // higher SH bands (DC is u itself)
};

// n Gaussians of SH degree `sh_degree`, drawn from mt19937_64(seed) in the
// order means, log-scales, quaternions, opacities, DC, higher bands.
inline GaussianModel RandomModel(size_t n, int sh_degree, uint64_t seed,
                                 const RandomModelRanges& ranges = {}) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (float& v : m.means) v = ranges.means * u(rng);
  for (float& v : m.log_scales) v = -3.f + ranges.log_scale_spread * u(rng);
  for (float& v : m.quats) v = u(rng);
  for (float& v : m.opacity_logits) v = ranges.opacity * u(rng);
  for (float& v : m.sh_dc) v = u(rng);
  for (float& v : m.sh_rest) v = ranges.sh_rest * u(rng);
  return m;
}

}  // namespace watergs
