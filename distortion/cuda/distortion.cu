// CUDA kernels of the 3D distortion layers (see distortion_kernels.h). The
// random numbers come from a counter-based SplitMix64 stream (one 64-bit
// seed per application, drawn by the host from the layer's rng), so they
// differ from the CPU layers' std::mt19937_64 draws but do not depend on
// the launch configuration.
#include <cub/cub.cuh>

#include "distortion/cuda/distortion_kernels.h"

namespace watergs {
namespace cuda_distortion {
namespace {

constexpr int kThreads = 256;
constexpr uint64_t kGolden = 0x9e3779b97f4a7c15ull;

unsigned Blocks(size_t count) {
  return static_cast<unsigned>((count + kThreads - 1) / kThreads);
}

// Value j of the SplitMix64 stream that starts at `seed`.
__device__ __forceinline__ uint64_t SplitMix64(uint64_t seed, uint64_t j) {
  uint64_t z = seed + (j + 1) * kGolden;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

__global__ void AddGaussianNoiseKernel(float* values, size_t count, float sigma,
                                       uint64_t seed) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= count) return;
  const uint64_t h = SplitMix64(seed, j);
  // u1 in (0, 1] keeps the logarithm finite.
  const double u1 = (double(h >> 32) + 1.0) * 0x1p-32;
  const double u2 = double(h & 0xffffffffull) * 0x1p-32;
  const double z = sqrt(-2.0 * log(u1)) * cospi(2.0 * u2);
  values[j] = __fadd_rn(values[j], static_cast<float>(sigma * z));
}

__global__ void DropoutKeysKernel(size_t n, uint64_t seed, uint32_t* keys,
                                  uint32_t* indices, uint32_t* keep) {
  const size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  keys[i] = static_cast<uint32_t>(SplitMix64(seed, i) >> 32);
  indices[i] = static_cast<uint32_t>(i);
  keep[i] = 1;
}

__global__ void MarkRemovedKernel(const uint32_t* sorted_indices,
                                  size_t removed, uint32_t* keep) {
  const size_t r = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (r < removed) keep[sorted_indices[r]] = 0;
}

__global__ void CompactKernel(const uint32_t* keep, const uint32_t* position,
                              size_t n, uint32_t* source) {
  const size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (i < n && keep[i]) source[position[i]] = static_cast<uint32_t>(i);
}

__global__ void CropSourceKernel(size_t n_out, size_t start, size_t removed,
                                 uint32_t* source) {
  const size_t o = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (o < n_out) source[o] = static_cast<uint32_t>(o < start ? o : o + removed);
}

__global__ void GatherRowsKernel(const float* in, const uint32_t* source,
                                 size_t n_out, int stride, float* out) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= n_out * stride) return;
  out[j] = in[size_t(source[j / stride]) * stride + j % stride];
}

__global__ void ScatterAddRowsKernel(const float* from, const uint32_t* source,
                                     size_t n_from, int stride, float* to) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= n_from * stride) return;
  float* dst = to + size_t(source[j / stride]) * stride + j % stride;
  *dst = __fadd_rn(*dst, from[j]);
}

__global__ void ScatterOrFlagsKernel(const uint8_t* from,
                                     const uint32_t* source, size_t n_from,
                                     uint8_t* to) {
  const size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (i < n_from) to[source[i]] |= from[i];
}

// The six n-element uint32 arrays of the dropout scratch, then CUB's space.
struct DropoutLayout {
  uint32_t *keys_in, *keys_out, *indices_in, *indices_out, *keep, *position;
  void* cub_temp;
  size_t cub_bytes;
};

size_t AlignUp(size_t bytes) { return (bytes + 255) / 256 * 256; }

size_t CubBytes(size_t n) {
  size_t sort_bytes = 0, scan_bytes = 0;
  const int items = static_cast<int>(n);
  cub::DeviceRadixSort::SortPairs(
      nullptr, sort_bytes, static_cast<const uint32_t*>(nullptr),
      static_cast<uint32_t*>(nullptr), static_cast<const uint32_t*>(nullptr),
      static_cast<uint32_t*>(nullptr), items);
  cub::DeviceScan::ExclusiveSum(nullptr, scan_bytes,
                                static_cast<const uint32_t*>(nullptr),
                                static_cast<uint32_t*>(nullptr), items);
  return sort_bytes > scan_bytes ? sort_bytes : scan_bytes;
}

DropoutLayout Carve(void* scratch, size_t n) {
  char* at = static_cast<char*>(scratch);
  const size_t array_bytes = AlignUp(n * sizeof(uint32_t));
  uint32_t* arrays[6];
  for (auto& a : arrays) {
    a = reinterpret_cast<uint32_t*>(at);
    at += array_bytes;
  }
  return {arrays[0], arrays[1], arrays[2], arrays[3],
          arrays[4], arrays[5], at,        CubBytes(n)};
}

}  // namespace

cudaError_t LaunchAddGaussianNoise(float* values, size_t count, float sigma,
                                   uint64_t seed, cudaStream_t stream) {
  if (count == 0) return cudaSuccess;
  AddGaussianNoiseKernel<<<Blocks(count), kThreads, 0, stream>>>(values, count,
                                                                 sigma, seed);
  return cudaGetLastError();
}

size_t DropoutScratchBytes(size_t n) {
  return 6 * AlignUp(n * sizeof(uint32_t)) + AlignUp(CubBytes(n));
}

cudaError_t LaunchDropoutSource(size_t n, size_t removed, uint64_t seed,
                                void* scratch, size_t scratch_bytes,
                                uint32_t* source, cudaStream_t stream) {
  if (n == 0) return cudaSuccess;
  if (scratch_bytes < DropoutScratchBytes(n)) return cudaErrorInvalidValue;
  DropoutLayout s = Carve(scratch, n);
  const int items = static_cast<int>(n);
  DropoutKeysKernel<<<Blocks(n), kThreads, 0, stream>>>(n, seed, s.keys_in,
                                                        s.indices_in, s.keep);
  cudaError_t status = cudaGetLastError();
  if (status != cudaSuccess) return status;
  // A stable LSD radix sort: equal keys keep index order.
  status = cub::DeviceRadixSort::SortPairs(s.cub_temp, s.cub_bytes, s.keys_in,
                                           s.keys_out, s.indices_in,
                                           s.indices_out, items, 0, 32, stream);
  if (status != cudaSuccess) return status;
  if (removed > 0) {
    MarkRemovedKernel<<<Blocks(removed), kThreads, 0, stream>>>(
        s.indices_out, removed, s.keep);
    status = cudaGetLastError();
    if (status != cudaSuccess) return status;
  }
  status = cub::DeviceScan::ExclusiveSum(s.cub_temp, s.cub_bytes, s.keep,
                                         s.position, items, stream);
  if (status != cudaSuccess) return status;
  CompactKernel<<<Blocks(n), kThreads, 0, stream>>>(s.keep, s.position, n,
                                                    source);
  return cudaGetLastError();
}

cudaError_t LaunchCropSource(size_t n, size_t start, size_t removed,
                             uint32_t* source, cudaStream_t stream) {
  const size_t n_out = n - removed;
  if (n_out == 0) return cudaSuccess;
  CropSourceKernel<<<Blocks(n_out), kThreads, 0, stream>>>(n_out, start,
                                                           removed, source);
  return cudaGetLastError();
}

cudaError_t LaunchGatherRows(const float* in, const uint32_t* source,
                             size_t n_out, int stride, float* out,
                             cudaStream_t stream) {
  if (n_out == 0 || stride == 0) return cudaSuccess;
  GatherRowsKernel<<<Blocks(n_out * stride), kThreads, 0, stream>>>(
      in, source, n_out, stride, out);
  return cudaGetLastError();
}

cudaError_t LaunchScatterAddRows(const float* from, const uint32_t* source,
                                 size_t n_from, int stride, float* to,
                                 cudaStream_t stream) {
  if (n_from == 0 || stride == 0) return cudaSuccess;
  ScatterAddRowsKernel<<<Blocks(n_from * stride), kThreads, 0, stream>>>(
      from, source, n_from, stride, to);
  return cudaGetLastError();
}

cudaError_t LaunchScatterOrFlags(const uint8_t* from, const uint32_t* source,
                                 size_t n_from, uint8_t* to,
                                 cudaStream_t stream) {
  if (n_from == 0) return cudaSuccess;
  ScatterOrFlagsKernel<<<Blocks(n_from), kThreads, 0, stream>>>(from, source,
                                                                n_from, to);
  return cudaGetLastError();
}

}  // namespace cuda_distortion
}  // namespace watergs
