// Launch API of the CUDA 3D distortion kernels (distortion.cu): position
// noise, the index lists of dropout and crop, and the row gather/scatter
// that apply them and carry gradients back. Plain C++17 (shared by nvcc and
// the host compiler); the host-facing layer is in cuda_distortion.h.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace watergs {
namespace cuda_distortion {

// values[j] += sigma * z_j, z_j ~ N(0, 1) by Box-Muller from the SplitMix64
// stream of `seed` at position j: the same seed gives the same noise for any
// launch configuration.
cudaError_t LaunchAddGaussianNoise(float* values, size_t count, float sigma,
                                   uint64_t seed, cudaStream_t stream);

// Bytes of scratch LaunchDropoutSource needs for n Gaussians.
size_t DropoutScratchBytes(size_t n);

// source[0 .. n - removed) = the kept indices in increasing order, where the
// `removed` dropped Gaussians are those with the smallest 32-bit SplitMix64
// keys of `seed` (ties to the lower index): a uniformly random subset of
// exactly `removed` Gaussians. n < 2^31.
cudaError_t LaunchDropoutSource(size_t n, size_t removed, uint64_t seed,
                                void* scratch, size_t scratch_bytes,
                                uint32_t* source, cudaStream_t stream);

// source[0 .. n - removed) = every index outside [start, start + removed).
cudaError_t LaunchCropSource(size_t n, size_t start, size_t removed,
                             uint32_t* source, cudaStream_t stream);

// out row i = in row source[i] (stride floats), i < n_out.
cudaError_t LaunchGatherRows(const float* in, const uint32_t* source,
                             size_t n_out, int stride, float* out,
                             cudaStream_t stream);

// to row source[i] += from row i, i < n_from. The source entries must be
// distinct (every layer's are), so no two threads add to one value.
cudaError_t LaunchScatterAddRows(const float* from, const uint32_t* source,
                                 size_t n_from, int stride, float* to,
                                 cudaStream_t stream);

// to[source[i]] |= from[i], i < n_from (distinct source entries): a
// visibility flag of a distorted Gaussian marks its source.
cudaError_t LaunchScatterOrFlags(const uint8_t* from, const uint32_t* source,
                                 size_t n_from, uint8_t* to,
                                 cudaStream_t stream);

}  // namespace cuda_distortion
}  // namespace watergs
