// Whether this build holds kernel code the visible GPU can run: a build for
// sm_90 finds a device on an older card, then fails at its first launch.
#include "gaussian/cuda/kernel_image.h"

namespace watergs {
namespace {

__global__ void ProbeKernel() {}

}  // namespace

cudaError_t CheckKernelImage() {
  cudaFuncAttributes attributes;
  return cudaFuncGetAttributes(&attributes, ProbeKernel);
}

}  // namespace watergs
