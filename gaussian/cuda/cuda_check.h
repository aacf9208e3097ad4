// CUDA error handling: every runtime call goes through WATERGS_CUDA_CHECK,
// which turns a failure into watergs::Error naming the call site and CUDA's
// message, so a GPU problem is a one-line error like any other.
#pragma once

#include <cuda_runtime.h>

#include <string>

#include "gaussian/util/error.h"

namespace watergs {

// Throws Error("<file>:<line>: CUDA <what>: <cuda message>") unless ok.
inline void CudaCheck(cudaError_t status, const char* what, const char* file,
                      int line) {
  if (status == cudaSuccess) return;
  Fail(std::string(file) + ":" + std::to_string(line) + ": CUDA " + what +
       ": " + cudaGetErrorString(status));
}

}  // namespace watergs

#define WATERGS_CUDA_CHECK(call) \
  ::watergs::CudaCheck((call), #call, __FILE__, __LINE__)
// After a kernel launch: launch errors (bad configuration) surface here.
#define WATERGS_CUDA_CHECK_LAUNCH() \
  ::watergs::CudaCheck(cudaGetLastError(), "kernel launch", __FILE__, __LINE__)
