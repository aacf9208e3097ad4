// gaussian/backend.h in a build without the CUDA backend: the CPU is the
// only device, and the host step always runs.
#include "gaussian/backend.h"
#include "gaussian/util/error.h"

namespace watergs {

bool GpuBackendAvailable(std::string* why) {
  if (why) {
    *why =
        "this watergs was built without the CUDA backend (no nvcc at build "
        "time, or -DWATERGS_CUDA=OFF)";
  }
  return false;
}

std::string GpuDescription() { return ""; }

void SynchronizeGpu() {}
void ResetGpuMemoryPeak() {}
void SampleGpuMemory() {}
size_t GpuMemoryPeakBytes() { return 0; }

std::unique_ptr<Rasterizer> MakeGpuRasterizer() {
  Fail("--device cuda: built without the CUDA backend");
}

DeviceTrainingStepFactory DeviceTrainingStepFor(Rasterizer&, const AdamOptions&,
                                                double, double) {
  return nullptr;
}

}  // namespace watergs
