// Tests of chunked quantisation: every value within half a step of its own
// chunk's range, chunks formed in Morton order, the order of the Gaussians
// kept, finer than one global range, hard cases, refusals.
#include "distortion/chunk_quantize.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "distortion/file_attacks.h"
#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/util/error.h"
#include "tests/common/random_model.h"

namespace watergs {
namespace {

GaussianModel Scene(size_t n, uint64_t seed) {
  RandomModelRanges ranges;
  ranges.means = 5;
  ranges.log_scale_spread = 1;
  ranges.opacity = 4;
  ranges.sh_rest = 0.3f;
  return RandomModel(n, 1, seed, ranges);
}

// Checks |after - before| <= step / 2 for each column of `stride` floats over
// each chunk (rows `order[begin, begin + 256)`), the step from the chunk's
// own range of `before` at `bits`. Returns the largest error / step seen.
double CheckColumns(const std::vector<float>& before,
                    const std::vector<float>& after, int stride, int bits,
                    const std::vector<uint32_t>& order) {
  double worst = 0;
  for (size_t begin = 0; begin < order.size(); begin += kQuantChunkSize) {
    const size_t end = std::min(order.size(), begin + kQuantChunkSize);
    for (int c = 0; c < stride; ++c) {
      double lo = INFINITY, hi = -INFINITY;
      for (size_t k = begin; k < end; ++k) {
        lo = std::min(lo, double(before[order[k] * stride + c]));
        hi = std::max(hi, double(before[order[k] * stride + c]));
      }
      const double step = (hi - lo) / ((1 << bits) - 1);
      for (size_t k = begin; k < end; ++k) {
        const double e = std::abs(double(after[order[k] * stride + c]) -
                                  double(before[order[k] * stride + c]));
        // float rounding of the level value on top of half a step
        EXPECT_LE(e, step / 2 + 1e-6 * (std::abs(hi) + std::abs(lo)))
            << "column " << c << " chunk " << begin / kQuantChunkSize;
        if (step > 0) worst = std::max(worst, e / step);
      }
    }
  }
  return worst;
}

TEST(ChunkQuantize, ErrorWithinHalfAStepOfTheChunkRange) {
  const GaussianModel in = Scene(1000, 1);  // 3 full chunks and a partial
  const std::vector<uint32_t> order = MortonOrder(in);
  std::mt19937_64 rng(0);
  GaussianModel out;
  std::vector<uint32_t> source;
  ApplyModelAttack(ParseModelAttack("quant_chunk:6:12"), in, rng, &out,
                   &source);
  ASSERT_EQ(out.size(), in.size());
  for (size_t i = 0; i < source.size(); ++i) ASSERT_EQ(source[i], i);
  // Rounding, not truncation: errors reach close to half a step.
  EXPECT_GT(CheckColumns(in.means, out.means, 3, 12, order), 0.4);
  EXPECT_GT(CheckColumns(in.log_scales, out.log_scales, 3, 6, order), 0.4);
  CheckColumns(in.sh_dc, out.sh_dc, 3, 6, order);
  CheckColumns(in.sh_rest, out.sh_rest, in.sh_rest_stride(), 6, order);
  // Opacity is quantised as alpha; rotations as unit quaternions, w >= 0.
  std::vector<float> alpha_in(in.size()), alpha_out(in.size());
  std::vector<float> q_in = in.quats;
  for (size_t i = 0; i < in.size(); ++i) {
    alpha_in[i] = float(OpacityLogitToAlpha(in.opacity_logits[i]));
    alpha_out[i] = float(OpacityLogitToAlpha(out.opacity_logits[i]));
    float* q = &q_in[4 * i];
    const double n =
        std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double sign = q[0] < 0 ? -1 : 1;
    for (int k = 0; k < 4; ++k) q[k] = float(sign * q[k] / n);
    EXPECT_GE(out.quats[4 * i], 0.f);
  }
  CheckColumns(alpha_in, alpha_out, 1, 6, order);
  CheckColumns(q_in, out.quats, 4, 6, order);
  // At most 2^bits distinct values per column and chunk.
  std::set<float> levels;
  for (size_t k = 0; k < kQuantChunkSize; ++k) {
    levels.insert(out.log_scales[3 * order[k]]);
  }
  EXPECT_LE(levels.size(), 64u);
  EXPECT_GT(levels.size(), 16u);
}

TEST(ChunkQuantize, FinerThanOneGlobalRange) {
  // 256 chunks of Morton neighbours each span about 1/256 of the volume:
  // their position error is far below the global quantiser's at the same
  // bits.
  const GaussianModel in = Scene(65536, 2);
  GaussianModel chunked = in, global = in;
  QuantizeChunked(8, 8, &chunked);
  QuantizeLinear(8, &global);
  double e_chunk = 0, e_global = 0;
  for (size_t k = 0; k < in.means.size(); ++k) {
    e_chunk += std::abs(chunked.means[k] - in.means[k]);
    e_global += std::abs(global.means[k] - in.means[k]);
  }
  EXPECT_LT(e_chunk, 0.5 * e_global);
}

TEST(ChunkQuantize, HardCasesStayFinite) {
  GaussianModel m = Scene(300, 3);
  m.opacity_logits[0] = -20.f;
  m.opacity_logits[1] = 20.f;
  m.log_scales[0] = kLogScaleFloor;
  for (int k = 0; k < 4; ++k) m.quats[4 * 2 + k] = 0.f;     // no rotation
  for (size_t i = 0; i < 300; ++i) m.sh_dc[3 * i] = 0.25f;  // constant
  QuantizeChunked(1, 1, &m);
  for (const std::vector<float>* a :
       {&m.means, &m.log_scales, &m.quats, &m.opacity_logits, &m.sh_dc,
        &m.sh_rest}) {
    for (float v : *a) ASSERT_TRUE(std::isfinite(v));
  }
  EXPECT_EQ(m.sh_dc[0], 0.25f);  // a constant column is exact
  GaussianModel empty;
  QuantizeChunked(8, 16, &empty);
  EXPECT_EQ(empty.size(), 0u);
}

TEST(ChunkQuantize, ParsesAndRefuses) {
  EXPECT_EQ(ToString(ParseModelAttack("quant_chunk:8")), "quant_chunk:8:16");
  EXPECT_EQ(ToString(ParseModelAttack("quant_chunk:6:11")), "quant_chunk:6:11");
  EXPECT_EQ(ParseModelAttackList("quant_chunk:8:12,sh0").size(), 2u);
  for (const char* bad :
       {"quant_chunk", "quant_chunk:0", "quant_chunk:17", "quant_chunk:8:0",
        "quant_chunk:8:25", "quant_chunk:8.5", "quant_chunk:8:x"}) {
    EXPECT_THROW(ParseModelAttack(bad), Error) << bad;
  }
  GaussianModel m = Scene(4, 1);
  EXPECT_THROW(QuantizeChunked(0, 8, &m), Error);
  EXPECT_THROW(QuantizeChunked(8, 30, &m), Error);
}

}  // namespace
}  // namespace watergs
