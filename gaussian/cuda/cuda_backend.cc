// The CUDA backend's answers to gaussian/backend.h.
#include <cuda_runtime.h>

#include "gaussian/backend.h"
#include "gaussian/cuda/cuda_device.h"
#include "gaussian/cuda/cuda_rasterizer.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/cuda_training_step.h"

namespace watergs {

bool GpuBackendAvailable(std::string* why) { return CudaDeviceVisible(why); }

std::string GpuDescription() { return CudaDeviceDescription(); }

void SynchronizeGpu() { cudaDeviceSynchronize(); }
void ResetGpuMemoryPeak() { ResetCudaMemoryPeak(); }
void SampleGpuMemory() { SampleCudaMemory(); }
size_t GpuMemoryPeakBytes() { return CudaMemoryPeakBytes(); }

std::unique_ptr<Rasterizer> MakeGpuRasterizer() { return MakeCudaRasterizer(); }

DeviceTrainingStepFactory DeviceTrainingStepFor(Rasterizer& rasterizer,
                                                const AdamOptions& adam,
                                                double scene_extent,
                                                double lambda_dssim) {
  auto* cuda = dynamic_cast<CudaRasterizer*>(&rasterizer);
  // Compact and bfloat16 moments have no CUDA Adam: those runs keep the
  // host step, with the CUDA rasterizer behind the host interface (same
  // results, but the model and gradients cross the bus every iteration).
  if (!cuda || adam.compact_moments || adam.half_moments) return nullptr;
  return [=](GaussianModel* host_model, Adam* host_adam) {
    return std::make_unique<CudaTrainingStep>(
        cuda, adam, scene_extent, lambda_dssim, host_model, host_adam);
  };
}

}  // namespace watergs
