// Decimation by merging neighbours, as 3DGS simplification tools do: pairs
// of nearest Gaussians are replaced by one Gaussian that matches the pair's
// first two moments, until the count is reduced by the requested fraction.
#pragma once

#include <cstdint>
#include <vector>

#include "gaussian/gaussian_model.h"

namespace watergs {

// Writes into Gaussian `into` of `out` (already sized, same SH degree as
// `in`) the moment-matched merge of Gaussians a and b of `in`:
//   weights w = opacity * volume (volume = product of the scales), made to
//   sum to 1 (equal if both are 0);
//   mean = w_a m_a + w_b m_b;
//   covariance = sum_k w_k (Sigma_k + (m_k - mean)(m_k - mean)^T), scales and
//   rotation from its eigen-decomposition (scales >= exp(kLogScaleFloor));
//   SH coefficients weighted by w;
//   opacity 1 - (1 - o_a)(1 - o_b), logit clamped to +-kOpacityLogitLimit.
// Finite for any finite-or-infinite input (degenerate scales, zero opacity).
void MergeGaussianPair(const GaussianModel& in, size_t a, size_t b,
                       GaussianModel* out, size_t into);

// out = `in` reduced to n - floor(fraction * n) Gaussians: in rounds, each
// Gaussian's nearest neighbour (nanoflann k-d tree on the means) is found,
// and the closest disjoint pairs merge (MergeGaussianPair) until the target
// is met (a round at most halves the count). Unmerged Gaussians keep their
// values and order first, merged ones follow; source[i] is the input index
// of output Gaussian i (for a merge, the pair's member of larger weight).
// fraction in [0, 1), else Error.
void Decimate(double fraction, const GaussianModel& in, GaussianModel* out,
              std::vector<uint32_t>* source);

}  // namespace watergs
