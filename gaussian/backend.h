// The boundary between the 3DGS engine and its compute backends. Device
// selection and the trainer ask here and never name a backend's types; each
// backend answers in its own folder: gaussian/cuda/cuda_backend.cc when the
// build has CUDA, gaussian/no_cuda/no_cuda_backend.cc otherwise (CMake
// compiles exactly one). Another backend is one more folder defining these.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "gaussian/adam.h"
#include "gaussian/device_training_step.h"
#include "gaussian/rasterizer.h"

namespace watergs {

// Whether the GPU backend is built and a GPU is visible; `why` (if not
// null) says why not in one line.
bool GpuBackendAvailable(std::string* why);

// One line naming GPU 0 ("NVIDIA H200, 139.8 GiB, compute 9.0"); empty
// without a GPU backend.
std::string GpuDescription();

// Waits for the GPU's queued work (timing asynchronous kernels); peak
// device memory in use since the reset, sampled by SampleGpuMemory (bytes).
// No-ops and 0 without a GPU backend.
void SynchronizeGpu();
void ResetGpuMemoryPeak();
void SampleGpuMemory();
size_t GpuMemoryPeakBytes();

// The GPU backend's rasterizer; Error when the build has none.
std::unique_ptr<Rasterizer> MakeGpuRasterizer();

// The step that keeps the model and Adam resident on the device behind
// `rasterizer`, or an empty factory when the host step runs (a CPU
// rasterizer, or optimiser moments the device has no Adam for).
DeviceTrainingStepFactory DeviceTrainingStepFor(Rasterizer& rasterizer,
                                                const AdamOptions& adam,
                                                double scene_extent,
                                                double lambda_dssim);

}  // namespace watergs
