// .splat reading and writing (see splat_io.h for the layout).
#include "gaussian/formats/splat_io.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

#include "gaussian/formats/codec_util.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr size_t kRecordBytes = 32;

}  // namespace

GaussianModel DecodeSplat(const std::string& name, const uint8_t* data,
                          size_t size, size_t* replaced) {
  if (size == 0) FailAt(name, "empty .splat file");
  if (size % kRecordBytes != 0) {
    FailAt(name, "size " + std::to_string(size) +
                     " bytes is not a multiple of the 32-byte .splat record");
  }
  const size_t n = size / kRecordBytes;
  GaussianModel model;
  model.sh_degree = 0;
  model.Resize(n);
  size_t zero_scales = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* r = data + i * kRecordBytes;
    for (int k = 0; k < 3; ++k) {
      const float x = codec::LoadF32(r + 4 * k);
      if (!std::isfinite(x)) {
        FailAt(name, "Gaussian " + std::to_string(i) +
                         " has a NaN/Inf position (not a .splat file?)");
      }
      model.means[3 * i + k] = x;
      const float s = codec::LoadF32(r + 12 + 4 * k);
      if (!(s >= 0) || !std::isfinite(s)) {
        FailAt(name, "Gaussian " + std::to_string(i) + " has scale " +
                         std::to_string(s) +
                         " (must be finite and >= 0; not a .splat file?)");
      }
      if (s == 0) {
        model.log_scales[3 * i + k] = kLogScaleFloor;
        ++zero_scales;
      } else {
        model.log_scales[3 * i + k] =
            std::max(kLogScaleFloor, float(std::log(double(s))));
      }
      model.sh_dc[3 * i + k] = float((r[24 + k] / 255.0 - 0.5) / codec::kShC0);
    }
    model.opacity_logits[i] = AlphaToOpacityLogit(r[27] / 255.0);
    double q[4], norm = 0;
    for (int k = 0; k < 4; ++k) {
      q[k] = (r[28 + k] - 128.0) / 128.0;
      norm += q[k] * q[k];
    }
    norm = std::sqrt(norm);
    for (int k = 0; k < 4; ++k) {
      model.quats[4 * i + k] =
          norm > 0 ? float(q[k] / norm) : (k == 0 ? 1.f : 0.f);
    }
  }
  if (replaced != nullptr) *replaced = zero_scales;
  return model;
}

std::string EncodeSplat(const GaussianModel& model) {
  const size_t bad = model.CountNonFinite();
  if (bad > 0) {
    Fail(".splat: cannot encode a model with " + std::to_string(bad) +
         " NaN/Inf values");
  }
  std::string out;
  out.reserve(model.size() * kRecordBytes);
  for (size_t i = 0; i < model.size(); ++i) {
    for (int k = 0; k < 3; ++k) codec::AppendF32(model.means[3 * i + k], &out);
    for (int k = 0; k < 3; ++k) {
      const double scale = std::exp(double(model.log_scales[3 * i + k]));
      codec::AppendF32(float(std::min<double>(scale, FLT_MAX)), &out);
    }
    for (int k = 0; k < 3; ++k) {
      const double rgb = 0.5 + codec::kShC0 * model.sh_dc[3 * i + k];
      out.push_back(char(codec::TruncClamp(rgb * 255, 255)));
    }
    out.push_back(char(codec::TruncClamp(
        OpacityLogitToAlpha(model.opacity_logits[i]) * 255, 255)));
    const auto q = codec::Normalized(&model.quats[4 * i]);
    for (int k = 0; k < 4; ++k) {
      out.push_back(char(codec::TruncClamp(q[k] * 128 + 128, 255)));
    }
  }
  return out;
}

void WriteSplat(const std::string& path, const GaussianModel& model) {
  std::string bytes;
  try {
    bytes = EncodeSplat(model);
  } catch (const Error& e) {
    FailAt(path, e.what());
  }
  AtomicWriteFile(path, bytes);
}

}  // namespace watergs
