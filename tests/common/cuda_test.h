// Shared by the CUDA parity tests: they run when this build has the CUDA
// backend and a GPU is visible, and skip with the reason otherwise.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "gaussian/device.h"

// Skips the current test, saying why, unless CUDA is usable.
#define WATERGS_REQUIRE_CUDA()                                          \
  do {                                                                  \
    std::string watergs_cuda_why;                                       \
    if (!::watergs::CudaAvailable(&watergs_cuda_why)) {                 \
      GTEST_SKIP() << "CUDA parity test skipped: " << watergs_cuda_why; \
    }                                                                   \
  } while (0)
