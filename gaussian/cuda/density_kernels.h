// Launch API of the CUDA adaptive density control kernels (density.cu): the
// per-Gaussian steps of gaussian/density_strategy.cc's Inria strategy
// (statistics, clone/split classification, split sampling, pruning, opacity
// reset) and CUB index compaction. Plain C++17 (shared by nvcc and the host
// compiler); the host-facing class is in cuda_density.h.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace watergs {
namespace cuda_density {

// Per Gaussian i < n with visible[i] != 0: grad_accum += grad_norm_ndc (when
// finite), denom += 1 (saturating at 65535), and max_radii = max(max_radii,
// radii) when radii (device, n) is not null.
cudaError_t LaunchAccumulate(const uint8_t* visible, const float* grad_norm_ndc,
                             const float* radii, size_t n, float* grad_accum,
                             uint16_t* denom, float* max_radii);

// Per Gaussian i < n, from the averaged NDC gradient norm and the largest
// scale exp(max log_scales[3i..3i+2]): keep[i] = 1 if the Gaussian stays
// (not selected, or cloned), clone[i] / split[i] = 1 if it is cloned / split.
cudaError_t LaunchClassify(const float* grad_accum, const uint16_t* denom,
                           const float* log_scales, size_t n,
                           float grad_threshold, float dense_scale,
                           uint8_t* keep, uint8_t* clone, uint8_t* split);

// out[j] = max_radii[parent[j]] for j < kept, 0 for kept <= j < n_out.
cudaError_t LaunchGatherRadii(const float* max_radii, const int64_t* parent,
                              size_t kept, size_t n_out, float* out);

// Split samples: rows first .. first + count of means (N x 3), log_scales
// (N x 3), quats (N x 4). normals (count x 3, standard normal, double) are
// scaled by exp(log_scale), rotated by the normalised quaternion and added
// to the mean; log_shrink = log(0.8 * split_samples) is subtracted from the
// log-scales.
cudaError_t LaunchApplySplits(const double* normals, size_t first, size_t count,
                              float log_shrink, float* means, float* log_scales,
                              const float* quats);

// Pruning rule of the Inria strategy for rows j < n. radii (n) is only read
// when size_limits. keep[j] = 0 if sigmoid(opacity) < min_opacity, or (when
// size_limits) max_screen_size > 0 and radii[j] > max_screen_size, or the
// largest scale > max_world_scale.
struct PruneRule {
  float min_opacity;
  bool size_limits;
  double max_screen_size;
  double max_world_scale;
};
cudaError_t LaunchPruneFlags(const float* opacity_logits,
                             const float* log_scales, const float* radii,
                             size_t n, const PruneRule& rule, uint8_t* keep);

// For j < n: parent_out[j] = parent[selected[j]] and adam_index[j] =
// parent_out[j] if selected[j] < kept (an original Gaussian), else -1 (a
// clone or split sample: fresh moments). selected may be null (identity).
cudaError_t LaunchComposeIndex(const int64_t* selected, const int64_t* parent,
                               size_t kept, size_t n, int64_t* parent_out,
                               int64_t* adam_index);

// Inria's reset_opacity (ResetOpacityLogit): logits whose sigmoid exceeds
// max_opacity become reset_logit = log(max_opacity / (1 - max_opacity)).
cudaError_t LaunchResetOpacity(float* logits, size_t n, double max_opacity,
                               float reset_logit);

// out[0..count) = the indices i < n with flags[i] != 0, ascending;
// *count_out (device) receives count. iota is n int64 scratch, scratch is
// reallocated by the call as CUB needs (cudaFree it when done).
cudaError_t SelectFlagged(const uint8_t* flags, size_t n, int64_t* iota,
                          int64_t* out, int64_t* count_out, void** scratch,
                          size_t* scratch_bytes);

}  // namespace cuda_density
}  // namespace watergs
