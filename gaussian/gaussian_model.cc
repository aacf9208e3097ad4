#include "gaussian/gaussian_model.h"

#include <algorithm>
#include <cmath>
#include <ostream>

namespace watergs {
namespace {

// SH band-0 constant, 1 / (2 sqrt(pi)).
constexpr float kShC0 = 0.28209479177387814f;

template <typename F>
void ForEachArray(GaussianModel& m, F&& f) {
  f(m.means, 3);
  f(m.log_scales, 3);
  f(m.quats, 4);
  f(m.opacity_logits, 1);
  f(m.sh_dc, 3);
  f(m.sh_rest, m.sh_rest_stride());
}

size_t CountNonFiniteIn(const std::vector<float>& v) {
  size_t n = 0;
  for (float x : v) n += std::isfinite(x) ? 0 : 1;
  return n;
}

}  // namespace

void GaussianModel::Resize(size_t n) {
  ForEachArray(*this, [n](std::vector<float>& v, int stride) {
    v.resize(n * static_cast<size_t>(stride), 0.f);
  });
}

size_t GaussianModel::CountNonFinite() const {
  return CountNonFiniteIn(means) + CountNonFiniteIn(log_scales) +
         CountNonFiniteIn(quats) + CountNonFiniteIn(opacity_logits) +
         CountNonFiniteIn(sh_dc) + CountNonFiniteIn(sh_rest);
}

void GaussianModel::Filter(const std::vector<bool>& keep) {
  const size_t n = size();
  ForEachArray(*this, [&](std::vector<float>& v, int stride) {
    size_t out = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!keep[i]) continue;
      for (int k = 0; k < stride; ++k) v[out * stride + k] = v[i * stride + k];
      ++out;
    }
    v.resize(out * stride);
  });
}

void GaussianModel::AppendFrom(const GaussianModel& other, size_t i) {
  auto append = [i](std::vector<float>& dst, const std::vector<float>& src,
                    int stride) {
    dst.insert(dst.end(), src.begin() + i * stride,
               src.begin() + (i + 1) * stride);
  };
  append(means, other.means, 3);
  append(log_scales, other.log_scales, 3);
  append(quats, other.quats, 4);
  append(opacity_logits, other.opacity_logits, 1);
  append(sh_dc, other.sh_dc, 3);
  append(sh_rest, other.sh_rest, sh_rest_stride());
}

float AlphaToOpacityLogit(double alpha) {
  if (std::isnan(alpha)) return static_cast<float>(alpha);
  if (alpha <= 0) return -kOpacityLogitLimit;
  if (alpha >= 1) return kOpacityLogitLimit;
  const double logit = std::log(alpha / (1.0 - alpha));
  return static_cast<float>(
      std::clamp<double>(logit, -kOpacityLogitLimit, kOpacityLogitLimit));
}

double OpacityLogitToAlpha(float logit) {
  return 1.0 / (1.0 + std::exp(-static_cast<double>(logit)));
}

void WarnInfinitiesReplaced(const std::string& path, size_t count,
                            std::ostream* out) {
  if (count == 0 || out == nullptr) return;
  *out << "warning: " << path << ": " << count
       << " infinite opacity logits or log-scales read as what viewers "
          "render (logit +-20 = alpha 0 or 1, log-scale -20 = flat)\n";
}

float RgbToShDc(float rgb) { return (rgb - 0.5f) / kShC0; }
float ShDcToRgb(float dc) { return dc * kShC0 + 0.5f; }

}  // namespace watergs
