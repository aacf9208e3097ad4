// Launch-free check that device 0 can run this build's kernels.
#pragma once

#include <cuda_runtime.h>

namespace watergs {

// cudaSuccess when this build has code for device 0 (SASS for its
// architecture or PTX it can compile), else the runtime's error
// (cudaErrorNoKernelImageForDevice, cudaErrorInvalidDeviceFunction).
cudaError_t CheckKernelImage();

}  // namespace watergs
