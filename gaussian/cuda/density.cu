// CUDA kernels of adaptive density control (see density_kernels.h), written
// to take the same decisions as gaussian/density_strategy.cc: the same float
// expressions in the same order through the *_rn intrinsics (no fused
// multiply-adds), and exp of float arguments evaluated in double and rounded
// to float, which matches the host's correctly rounded expf except in
// vanishingly rare ties. No decision (threshold or comparison) involves a
// multiply-add, so a host build that fuses them (-march=native) can only
// move split-sample means by a double rounding of their offset. Index math
// is in size_t / int64 throughout.
#include <cub/cub.cuh>

#include "gaussian/cuda/density_kernels.h"

namespace watergs {
namespace cuda_density {
namespace {

constexpr int kThreads = 256;

unsigned Blocks(size_t n) {
  return static_cast<unsigned>((n + kThreads - 1) / kThreads);
}

__device__ __forceinline__ size_t ThreadIndex() {
  return blockIdx.x * size_t(blockDim.x) + threadIdx.x;
}

__device__ __forceinline__ float ExpF(float x) {
  return static_cast<float>(exp(static_cast<double>(x)));
}

// density_strategy.cc's Sigmoid: 1 / (1 + exp(-x)) in float.
__device__ __forceinline__ float Sigmoid(float x) {
  return __fdiv_rn(1.f, __fadd_rn(1.f, ExpF(-x)));
}

// density_strategy.cc's MaxScale: exp of the largest log-scale, taken as
// std::max({a, b, c}) does (first of equals, NaN only if first).
__device__ __forceinline__ float MaxScale(const float* s) {
  float m = s[0];
  if (m < s[1]) m = s[1];
  if (m < s[2]) m = s[2];
  return ExpF(m);
}

__global__ void AccumulateKernel(const uint8_t* visible,
                                 const float* grad_norm_ndc, const float* radii,
                                 size_t n, float* grad_accum, uint16_t* denom,
                                 float* max_radii) {
  const size_t i = ThreadIndex();
  if (i >= n || !visible[i]) return;
  const float g = grad_norm_ndc[i];
  if (isfinite(g)) grad_accum[i] = __fadd_rn(grad_accum[i], g);
  if (denom[i] < 65535) denom[i] = static_cast<uint16_t>(denom[i] + 1);
  if (radii) {
    const float r = radii[i];
    if (max_radii[i] < r) max_radii[i] = r;
  }
}

__global__ void ClassifyKernel(const float* grad_accum, const uint16_t* denom,
                               const float* log_scales, size_t n,
                               float grad_threshold, float dense_scale,
                               uint8_t* keep, uint8_t* clone, uint8_t* split) {
  const size_t i = ThreadIndex();
  if (i >= n) return;
  const float avg = denom[i] > 0
                        ? __fdiv_rn(grad_accum[i], static_cast<float>(denom[i]))
                        : 0.f;
  const bool selected = avg >= grad_threshold;
  const bool cloned = selected && MaxScale(&log_scales[3 * i]) <= dense_scale;
  keep[i] = !selected || cloned;
  clone[i] = cloned;
  split[i] = selected && !cloned;
}

__global__ void GatherRadiiKernel(const float* max_radii, const int64_t* parent,
                                  size_t kept, size_t n_out, float* out) {
  const size_t j = ThreadIndex();
  if (j >= n_out) return;
  out[j] = j < kept ? max_radii[parent[j]] : 0.f;
}

// density_strategy.cc's Rotation (row-major, double) of a quaternion
// (w, x, y, z), normalised; zero or non-finite -> identity.
__device__ void Rotation(const float* q, double* R) {
  double w = q[0], x = q[1], y = q[2], z = q[3];
  const double n = __dsqrt_rn(__dadd_rn(
      __dadd_rn(__dadd_rn(__dmul_rn(w, w), __dmul_rn(x, x)), __dmul_rn(y, y)),
      __dmul_rn(z, z)));
  if (!(n > 1e-12) || !isfinite(n)) {
    w = 1, x = y = z = 0;
  } else {
    w = __ddiv_rn(w, n), x = __ddiv_rn(x, n), y = __ddiv_rn(y, n),
    z = __ddiv_rn(z, n);
  }
  const double xx = __dmul_rn(x, x), yy = __dmul_rn(y, y), zz = __dmul_rn(z, z);
  R[0] = __dsub_rn(1.0, __dmul_rn(2.0, __dadd_rn(yy, zz)));
  R[1] = __dmul_rn(2.0, __dsub_rn(__dmul_rn(x, y), __dmul_rn(w, z)));
  R[2] = __dmul_rn(2.0, __dadd_rn(__dmul_rn(x, z), __dmul_rn(w, y)));
  R[3] = __dmul_rn(2.0, __dadd_rn(__dmul_rn(x, y), __dmul_rn(w, z)));
  R[4] = __dsub_rn(1.0, __dmul_rn(2.0, __dadd_rn(xx, zz)));
  R[5] = __dmul_rn(2.0, __dsub_rn(__dmul_rn(y, z), __dmul_rn(w, x)));
  R[6] = __dmul_rn(2.0, __dsub_rn(__dmul_rn(x, z), __dmul_rn(w, y)));
  R[7] = __dmul_rn(2.0, __dadd_rn(__dmul_rn(y, z), __dmul_rn(w, x)));
  R[8] = __dsub_rn(1.0, __dmul_rn(2.0, __dadd_rn(xx, yy)));
}

__global__ void ApplySplitsKernel(const double* normals, size_t first,
                                  size_t count, float log_shrink, float* means,
                                  float* log_scales, const float* quats) {
  const size_t k = ThreadIndex();
  if (k >= count) return;
  const size_t j = first + k;
  float* mean = &means[3 * j];
  float* log_scale = &log_scales[3 * j];
  double R[9];
  Rotation(&quats[4 * j], R);
  double local[3];
  for (int a = 0; a < 3; ++a) {
    local[a] =
        __dmul_rn(normals[3 * k + a], exp(static_cast<double>(log_scale[a])));
  }
  for (int r = 0; r < 3; ++r) {
    const double offset =
        __dadd_rn(__dadd_rn(__dmul_rn(R[3 * r], local[0]),
                            __dmul_rn(R[3 * r + 1], local[1])),
                  __dmul_rn(R[3 * r + 2], local[2]));
    mean[r] = __fadd_rn(mean[r], static_cast<float>(offset));
  }
  for (int a = 0; a < 3; ++a) {
    log_scale[a] = __fsub_rn(log_scale[a], log_shrink);
  }
}

__global__ void PruneFlagsKernel(const float* opacity_logits,
                                 const float* log_scales, const float* radii,
                                 size_t n, PruneRule rule, uint8_t* keep) {
  const size_t j = ThreadIndex();
  if (j >= n) return;
  bool prune = Sigmoid(opacity_logits[j]) < rule.min_opacity;
  if (rule.size_limits) {
    if (rule.max_screen_size > 0 &&
        static_cast<double>(radii[j]) > rule.max_screen_size) {
      prune = true;
    }
    if (static_cast<double>(MaxScale(&log_scales[3 * j])) >
        rule.max_world_scale) {
      prune = true;
    }
  }
  keep[j] = !prune;
}

__global__ void ComposeIndexKernel(const int64_t* selected,
                                   const int64_t* parent, size_t kept, size_t n,
                                   int64_t* parent_out, int64_t* adam_index) {
  const size_t j = ThreadIndex();
  if (j >= n) return;
  const int64_t s = selected ? selected[j] : static_cast<int64_t>(j);
  parent_out[j] = parent[s];
  adam_index[j] = s < static_cast<int64_t>(kept) ? parent[s] : -1;
}

__global__ void ResetOpacityKernel(float* logits, size_t n, double max_opacity,
                                   float reset_logit) {
  const size_t i = ThreadIndex();
  if (i >= n) return;
  if (static_cast<double>(Sigmoid(logits[i])) > max_opacity) {
    logits[i] = reset_logit;
  }
}

__global__ void IotaKernel(int64_t* out, size_t n) {
  const size_t i = ThreadIndex();
  if (i < n) out[i] = static_cast<int64_t>(i);
}

}  // namespace

cudaError_t LaunchAccumulate(const uint8_t* visible, const float* grad_norm_ndc,
                             const float* radii, size_t n, float* grad_accum,
                             uint16_t* denom, float* max_radii) {
  if (n == 0) return cudaSuccess;
  AccumulateKernel<<<Blocks(n), kThreads>>>(visible, grad_norm_ndc, radii, n,
                                            grad_accum, denom, max_radii);
  return cudaGetLastError();
}

cudaError_t LaunchClassify(const float* grad_accum, const uint16_t* denom,
                           const float* log_scales, size_t n,
                           float grad_threshold, float dense_scale,
                           uint8_t* keep, uint8_t* clone, uint8_t* split) {
  if (n == 0) return cudaSuccess;
  ClassifyKernel<<<Blocks(n), kThreads>>>(grad_accum, denom, log_scales, n,
                                          grad_threshold, dense_scale, keep,
                                          clone, split);
  return cudaGetLastError();
}

cudaError_t LaunchGatherRadii(const float* max_radii, const int64_t* parent,
                              size_t kept, size_t n_out, float* out) {
  if (n_out == 0) return cudaSuccess;
  GatherRadiiKernel<<<Blocks(n_out), kThreads>>>(max_radii, parent, kept, n_out,
                                                 out);
  return cudaGetLastError();
}

cudaError_t LaunchApplySplits(const double* normals, size_t first, size_t count,
                              float log_shrink, float* means, float* log_scales,
                              const float* quats) {
  if (count == 0) return cudaSuccess;
  ApplySplitsKernel<<<Blocks(count), kThreads>>>(
      normals, first, count, log_shrink, means, log_scales, quats);
  return cudaGetLastError();
}

cudaError_t LaunchPruneFlags(const float* opacity_logits,
                             const float* log_scales, const float* radii,
                             size_t n, const PruneRule& rule, uint8_t* keep) {
  if (n == 0) return cudaSuccess;
  PruneFlagsKernel<<<Blocks(n), kThreads>>>(opacity_logits, log_scales, radii,
                                            n, rule, keep);
  return cudaGetLastError();
}

cudaError_t LaunchComposeIndex(const int64_t* selected, const int64_t* parent,
                               size_t kept, size_t n, int64_t* parent_out,
                               int64_t* adam_index) {
  if (n == 0) return cudaSuccess;
  ComposeIndexKernel<<<Blocks(n), kThreads>>>(selected, parent, kept, n,
                                              parent_out, adam_index);
  return cudaGetLastError();
}

cudaError_t LaunchResetOpacity(float* logits, size_t n, double max_opacity,
                               float reset_logit) {
  if (n == 0) return cudaSuccess;
  ResetOpacityKernel<<<Blocks(n), kThreads>>>(logits, n, max_opacity,
                                              reset_logit);
  return cudaGetLastError();
}

cudaError_t SelectFlagged(const uint8_t* flags, size_t n, int64_t* iota,
                          int64_t* out, int64_t* count_out, void** scratch,
                          size_t* scratch_bytes) {
  if (n == 0) return cudaMemset(count_out, 0, sizeof(int64_t));
  IotaKernel<<<Blocks(n), kThreads>>>(iota, n);
  cudaError_t status = cudaGetLastError();
  if (status != cudaSuccess) return status;
  const int64_t num_items = static_cast<int64_t>(n);
  size_t needed = 0;
  status = cub::DeviceSelect::Flagged(nullptr, needed, iota, flags, out,
                                      count_out, num_items);
  if (status != cudaSuccess) return status;
  if (needed > *scratch_bytes) {
    cudaFree(*scratch);
    *scratch = nullptr;
    *scratch_bytes = 0;
    status = cudaMalloc(scratch, needed);
    if (status != cudaSuccess) return status;
    *scratch_bytes = needed;
  }
  return cub::DeviceSelect::Flagged(*scratch, needed, iota, flags, out,
                                    count_out, num_items);
}

}  // namespace cuda_density
}  // namespace watergs
