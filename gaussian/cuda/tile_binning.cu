// CUDA tile binning: the GPU form of tile_binning.cc. Instead of a counting
// sort of depth-sorted splats, every (Gaussian, tile) pair gets a 64-bit key
// (tile index << 32 | depth bits) and one stable CUB radix sort orders them
// by tile, then depth, then Gaussian id (pairs are written in id order), the
// CPU's (depth, id) order inside each tile; tile ranges are then read off
// the sorted keys.
#include <cuda_runtime.h>

#include <cstdint>
#include <cub/cub.cuh>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/raster_kernels.h"

namespace watergs::cuda_raster {
namespace {

constexpr int kThreads = 256;

// Bits of a float that sort as unsigned integers in the float's order
// (depths are >= the near plane, which may be <= 0).
__device__ uint32_t OrderedBits(float value) {
  const uint32_t bits = __float_as_uint(value);
  return bits & 0x80000000u ? ~bits : bits | 0x80000000u;
}

__global__ void DuplicateKeysKernel(int n, const TileRect* tiles,
                                    const float* depth, const uint64_t* counts,
                                    const uint64_t* offsets,
                                    TileRect render_tiles, uint64_t* keys,
                                    uint32_t* ids) {
  // 64-bit: blockIdx.x * blockDim.x overflows int for n near 2^31.
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n || counts[i] == 0) return;
  const TileRect t = tiles[i];
  const int range_w = render_tiles.x1 - render_tiles.x0;
  const uint64_t depth_bits = OrderedBits(depth[i]);
  uint64_t pos = offsets[i] - counts[i];
  for (int ty = t.y0; ty < t.y1; ++ty) {
    for (int tx = t.x0; tx < t.x1; ++tx) {
      const uint64_t tile =
          static_cast<uint64_t>(ty - render_tiles.y0) * range_w +
          static_cast<uint64_t>(tx - render_tiles.x0);
      keys[pos] = tile << 32 | depth_bits;
      ids[pos] = static_cast<uint32_t>(i);
      ++pos;
    }
  }
}

// Entry k starts its tile's run if its tile differs from entry k - 1's, and
// ends it if it differs from entry k + 1's.
__global__ void TileRangesKernel(const uint64_t* keys, size_t entries,
                                 uint32_t* ranges) {
  const size_t k = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= entries) return;
  const uint32_t tile = static_cast<uint32_t>(keys[k] >> 32);
  if (k == 0 || static_cast<uint32_t>(keys[k - 1] >> 32) != tile) {
    ranges[2 * tile] = static_cast<uint32_t>(k);
  }
  if (k + 1 == entries || static_cast<uint32_t>(keys[k + 1] >> 32) != tile) {
    ranges[2 * tile + 1] = static_cast<uint32_t>(k + 1);
  }
}

}  // namespace

size_t ScanScratchBytes(int n) {
  size_t bytes = 0;
  WATERGS_CUDA_CHECK(cub::DeviceScan::InclusiveSum(
      nullptr, bytes, static_cast<const uint64_t*>(nullptr),
      static_cast<uint64_t*>(nullptr), n));
  return bytes;
}

void LaunchScanTileCounts(const uint64_t* counts, uint64_t* offsets, int n,
                          void* scratch, size_t scratch_bytes) {
  if (n <= 0) return;
  WATERGS_CUDA_CHECK(cub::DeviceScan::InclusiveSum(scratch, scratch_bytes,
                                                   counts, offsets, n));
}

void LaunchDuplicateKeys(int n, const TileRect* tiles, const float* depth,
                         const uint64_t* counts, const uint64_t* offsets,
                         TileRect render_tiles, uint64_t* keys, uint32_t* ids) {
  if (n <= 0) return;
  const int64_t blocks = (static_cast<int64_t>(n) + kThreads - 1) / kThreads;
  DuplicateKeysKernel<<<static_cast<unsigned>(blocks), kThreads>>>(
      n, tiles, depth, counts, offsets, render_tiles, keys, ids);
  WATERGS_CUDA_CHECK_LAUNCH();
}

int SortKeyBits(int num_tiles) {
  int tile_bits = 0;
  while (tile_bits < 31 &&
         (1u << tile_bits) < static_cast<unsigned>(num_tiles)) {
    ++tile_bits;
  }
  return 32 + tile_bits;
}

size_t SortScratchBytes(size_t entries, int key_bits) {
  size_t bytes = 0;
  WATERGS_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(
      nullptr, bytes, static_cast<const uint64_t*>(nullptr),
      static_cast<uint64_t*>(nullptr), static_cast<const uint32_t*>(nullptr),
      static_cast<uint32_t*>(nullptr), static_cast<int64_t>(entries), 0,
      key_bits));
  return bytes;
}

void LaunchSortPairs(const uint64_t* keys_in, uint64_t* keys_out,
                     const uint32_t* ids_in, uint32_t* ids_out, size_t entries,
                     int key_bits, void* scratch, size_t scratch_bytes) {
  if (entries == 0) return;
  WATERGS_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(
      scratch, scratch_bytes, keys_in, keys_out, ids_in, ids_out,
      static_cast<int64_t>(entries), 0, key_bits));
}

void LaunchTileRanges(const uint64_t* sorted_keys, size_t entries,
                      uint32_t* ranges) {
  if (entries == 0) return;
  const size_t blocks = (entries + kThreads - 1) / kThreads;
  TileRangesKernel<<<static_cast<unsigned>(blocks), kThreads>>>(
      sorted_keys, entries, ranges);
  WATERGS_CUDA_CHECK_LAUNCH();
}

}  // namespace watergs::cuda_raster
