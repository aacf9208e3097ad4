// Runtime checks of the GPU: whether one is visible, its name and memory.
#pragma once

#include <string>

namespace watergs {

// True if the CUDA runtime sees at least one device and this build has
// kernels it can run; else `why` says why.
bool CudaDeviceVisible(std::string* why);

// "NVIDIA H100 80GB HBM3, 79.1 GiB, compute 9.0" for device 0.
std::string CudaDeviceDescription();

// Peak device memory in use since the last reset, bytes (from
// cudaMemGetInfo sampled by SampleCudaMemory), and the sampler itself.
void ResetCudaMemoryPeak();
void SampleCudaMemory();
size_t CudaMemoryPeakBytes();

}  // namespace watergs
