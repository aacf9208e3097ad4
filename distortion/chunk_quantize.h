// Quantisation as compressed 3DGS formats apply it (PlayCanvas compressed
// PLY, SOG): the Gaussians in Morton order (splat-transform's), cut into
// chunks of 256 neighbours, every attribute rounded to 2^bits levels between
// its own chunk's min and max. Unlike one global range per attribute
// (QuantizeLinear, a stress test), a chunk spans a small region, so the steps
// stay small where the scene has detail.
#pragma once

#include "gaussian/gaussian_model.h"

namespace watergs {

// Gaussians per quantisation chunk (compressed PLY's).
inline constexpr int kQuantChunkSize = 256;

// In place; the order of the Gaussians is kept (the Morton order only forms
// the chunks). Per chunk and per column, with step = (max - min) /
// (2^b - 1) and the value replaced by min + round((v - min) / step) * step,
// so |error| <= step / 2:
//   x, y, z: b = position_bits;
//   log-scales (quantised in log space, as stored): b = bits;
//   rotation: normalised, sign chosen so that w >= 0, each of w x y z: bits;
//   opacity: sigmoid(logit) quantised (bits), logit back clamped to
//   +-kOpacityLogitLimit;
//   SH DC and each higher coefficient: bits.
// bits in [1, 16], position_bits in [1, 24], else Error.
void QuantizeChunked(int bits, int position_bits, GaussianModel* model);

}  // namespace watergs
