// GPU presence and memory figures through the CUDA runtime.
#include "gaussian/cuda/cuda_device.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/kernel_image.h"

namespace watergs {
namespace {

// Bytes in use at the first sample after a reset, and the largest since.
size_t g_baseline_used = 0, g_peak_used = 0;

size_t DeviceBytesInUse() {
  size_t free_bytes = 0, total_bytes = 0;
  WATERGS_CUDA_CHECK(cudaMemGetInfo(&free_bytes, &total_bytes));
  return total_bytes - free_bytes;
}

}  // namespace

bool CudaDeviceVisible(std::string* why) {
  int count = 0;
  const cudaError_t status = cudaGetDeviceCount(&count);
  if (status != cudaSuccess) {
    if (why) {
      *why =
          std::string("no CUDA device visible: ") + cudaGetErrorString(status);
    }
    cudaGetLastError();  // clear the sticky error for later calls
    return false;
  }
  if (count == 0) {
    if (why) *why = "no CUDA device visible (cudaGetDeviceCount = 0)";
    return false;
  }
  const cudaError_t image = CheckKernelImage();
  if (image != cudaSuccess) {
    if (why) {
      cudaDeviceProp prop{};
      cudaGetDeviceProperties(&prop, 0);
      *why = std::string(prop.name) + " (compute " +
             std::to_string(prop.major) + "." + std::to_string(prop.minor) +
             ") cannot run this build's kernels (" + cudaGetErrorString(image) +
             "; rebuild with -DCMAKE_CUDA_ARCHITECTURES=" +
             std::to_string(prop.major) + std::to_string(prop.minor) + ")";
    }
    cudaGetLastError();
    return false;
  }
  return true;
}

std::string CudaDeviceDescription() {
  cudaDeviceProp prop{};
  WATERGS_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
  char memory[64];
  std::snprintf(memory, sizeof(memory), "%.1f GiB",
                prop.totalGlobalMem / double(1 << 30));
  return std::string(prop.name) + ", " + memory + ", compute " +
         std::to_string(prop.major) + "." + std::to_string(prop.minor);
}

void ResetCudaMemoryPeak() {
  g_baseline_used = DeviceBytesInUse();
  g_peak_used = g_baseline_used;
}

void SampleCudaMemory() {
  g_peak_used = std::max(g_peak_used, DeviceBytesInUse());
}

size_t CudaMemoryPeakBytes() { return g_peak_used - g_baseline_used; }

}  // namespace watergs
