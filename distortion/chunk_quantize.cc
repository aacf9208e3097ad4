// Chunked quantisation (see chunk_quantize.h).
#include "distortion/chunk_quantize.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Quantises values[rows[k] * stride + column] for the rows of one chunk.
void QuantizeChunkColumn(int bits, const uint32_t* rows, size_t count,
                         int stride, int column, std::vector<float>* values) {
  double lo = INFINITY, hi = -INFINITY;
  for (size_t k = 0; k < count; ++k) {
    const double v = (*values)[size_t(rows[k]) * stride + column];
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  // In double: hi - lo of floats cannot overflow, and the levels stay exact.
  const double step = (hi - lo) / double((1u << bits) - 1);
  if (!(step > 0) || !std::isfinite(step)) return;  // constant column
  for (size_t k = 0; k < count; ++k) {
    float& v = (*values)[size_t(rows[k]) * stride + column];
    const double level = std::round((double(v) - lo) / step);
    v = float(std::clamp(lo + level * step, lo, hi));
  }
}

void QuantizeChunkArray(int bits, const uint32_t* rows, size_t count,
                        int stride, std::vector<float>* values) {
  for (int column = 0; column < stride; ++column) {
    QuantizeChunkColumn(bits, rows, count, stride, column, values);
  }
}

}  // namespace

void QuantizeChunked(int bits, int position_bits, GaussianModel* model) {
  if (bits < 1 || bits > 16) {
    Fail("--attack: quant_chunk: bits must be in [1, 16], not " +
         std::to_string(bits));
  }
  if (position_bits < 1 || position_bits > 24) {
    Fail("--attack: quant_chunk: position bits must be in [1, 24], not " +
         std::to_string(position_bits));
  }
  const size_t n = model->size();
  if (n == 0) return;
  // Rotations in the form a codec stores: unit length, w >= 0 (q and -q are
  // the same rotation).
  for (size_t i = 0; i < n; ++i) {
    float* q = &model->quats[4 * i];
    const double norm = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] +
                                  double(q[2]) * q[2] + double(q[3]) * q[3]);
    if (!(norm > 0) || !std::isfinite(norm)) {
      q[0] = 1, q[1] = q[2] = q[3] = 0;
      continue;
    }
    const double sign = q[0] < 0 ? -1.0 : 1.0;
    for (int k = 0; k < 4; ++k) q[k] = float(sign * q[k] / norm);
  }
  std::vector<float> opacity(n);
  for (size_t i = 0; i < n; ++i) {
    opacity[i] = float(OpacityLogitToAlpha(model->opacity_logits[i]));
  }
  const std::vector<uint32_t> order = MortonOrder(*model);
  const int rest = model->sh_rest_stride();
  for (size_t begin = 0; begin < n; begin += kQuantChunkSize) {
    const size_t count = std::min<size_t>(kQuantChunkSize, n - begin);
    const uint32_t* rows = order.data() + begin;
    QuantizeChunkArray(position_bits, rows, count, 3, &model->means);
    QuantizeChunkArray(bits, rows, count, 3, &model->log_scales);
    QuantizeChunkArray(bits, rows, count, 4, &model->quats);
    QuantizeChunkArray(bits, rows, count, 1, &opacity);
    QuantizeChunkArray(bits, rows, count, 3, &model->sh_dc);
    if (rest > 0) QuantizeChunkArray(bits, rows, count, rest, &model->sh_rest);
  }
  for (size_t i = 0; i < n; ++i) {
    model->opacity_logits[i] = AlphaToOpacityLogit(opacity[i]);
  }
}

}  // namespace watergs
