// LightGaussian's significance pruning (Fan et al. 2023, "global
// significance"): every Gaussian is scored by the blending weight it gives
// the training views' pixels, sum over cameras and pixels of alpha * T,
// times LightGaussian's volume factor (volume / the 90th-percentile volume)
// ^ 0.1 (its default v_pow), and the lowest-scored fraction is removed. What
// a compaction pipeline does to a watermarked file before publishing it.
#pragma once

#include <cstdint>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// LightGaussian's exponent on the normalised volume (its v_pow default).
inline constexpr double kSignificanceVolumePower = 0.1;

// Per Gaussian: the summed blend weight over `cameras` (rendered with
// `rasterizer`), times (volume / p90 volume) ^ volume_power with the volume
// the product of the three scales. Finite and >= 0 for any model: a
// Gaussian no camera sees, or of zero opacity, scores 0. Throws Error if
// `cameras` is empty.
std::vector<double> SignificanceScores(
    const GaussianModel& model, const std::vector<RenderCamera>& cameras,
    Rasterizer& rasterizer, double volume_power = kSignificanceVolumePower);

// out = `in` without the floor(fraction * n) Gaussians of lowest `scores`
// (ties removed in index order), order kept; source[i] is the input index of
// output Gaussian i. fraction in [0, 1), else Error.
void PruneLowestScores(double fraction, const std::vector<double>& scores,
                       const GaussianModel& in, GaussianModel* out,
                       std::vector<uint32_t>* source);

}  // namespace watergs
