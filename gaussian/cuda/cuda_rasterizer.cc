// Placeholder until the CUDA rasterizer stages land (replaced by them).
#include "gaussian/cuda/cuda_rasterizer.h"

#include "gaussian/error.h"

namespace watergs {

std::unique_ptr<Rasterizer> MakeCudaRasterizer() {
  Fail("--device cuda: the CUDA rasterizer is not implemented yet");
}

}  // namespace watergs
