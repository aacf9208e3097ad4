// The CUDA rasterizer behind the Rasterizer interface (rasterizer.h): the
// same stages as the CPU one (projection + SH colour, tile binning with a
// CUB device radix sort on (tile, depth) keys, tile-wise blending forward,
// reverse-order backward), tested for parity against it
// (tests/gaussian/cuda_rasterizer_test.cc).
#pragma once

#include <memory>

#include "gaussian/rasterizer.h"

namespace watergs {

// Throws Error if no CUDA device is usable.
std::unique_ptr<Rasterizer> MakeCudaRasterizer();

}  // namespace watergs
