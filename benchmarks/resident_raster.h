// Rasterizer timings with the model, image and gradients resident on the GPU
// (what a device-resident trainer pays each iteration, and what users compare
// with gsplat's), next to the host interface raster_benchmark times. Defined
// in benchmarks/cuda/ with the CUDA backend and in benchmarks/no_cuda/
// (ok = false) without it.
#pragma once

#include "gaussian/camera.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs::bench {

struct ResidentRasterTiming {
  // False without a GPU backend.
  bool ok = false;
  // Medians in milliseconds (CUDA events around each call).
  double forward_ms = 0, backward_ms = 0, both_ms = 0;
};

// Uploads `model` once, then times `repeats` forward and backward passes of
// the device entry points after one untimed pass (factored SH gradients, as
// the device-resident trainer takes them).
ResidentRasterTiming TimeResidentRaster(const GaussianModel& model,
                                        const RenderCamera& camera,
                                        const RenderOptions& options,
                                        int repeats);

}  // namespace watergs::bench
