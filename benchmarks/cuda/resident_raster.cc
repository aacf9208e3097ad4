// benchmarks/resident_raster.h on the CUDA backend: CudaRasterizer's
// ForwardDevice / BackwardDevice on arrays uploaded once.
#include "benchmarks/resident_raster.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <memory>
#include <random>
#include <vector>

#include "benchmarks/benchmark_util.h"
#include "gaussian/cpu_rasterizer.h"
#include "gaussian/cuda/compact_gradient_buffers.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/cuda_model_mirror.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"

namespace watergs::bench {

ResidentRasterTiming TimeResidentRaster(const GaussianModel& model,
                                        const RenderCamera& camera,
                                        const RenderOptions& options,
                                        int repeats) {
  CudaRasterizer rasterizer;
  DeviceGaussianArrays arrays;
  arrays.Upload(model);
  const PixelRect rect = ResolveRenderRect(camera, options);
  const size_t channels = size_t(rect.width) * rect.height * 3;
  DeviceBuffer<float> image(channels), grad_image(channels);
  std::vector<float> host_grad(channels);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> small(-1e-5f, 1e-5f);
  for (float& g : host_grad) g = small(rng);
  grad_image.Upload(host_grad);

  CompactGradientBuffers buffers;
  const CudaGradientArrays grads = buffers.Resize(model.size());

  const CudaModelArrays resident = arrays.Arrays();
  std::unique_ptr<RenderContext> context;
  auto pass = [&](cudaEvent_t start, cudaEvent_t mid, cudaEvent_t end) {
    WATERGS_CUDA_CHECK(cudaEventRecord(start));
    rasterizer.ForwardDevice(resident, camera, options, image.data(), &context);
    WATERGS_CUDA_CHECK(cudaEventRecord(mid));
    rasterizer.BackwardDevice(*context, grad_image.data(), grads);
    WATERGS_CUDA_CHECK(cudaEventRecord(end));
    WATERGS_CUDA_CHECK(cudaEventSynchronize(end));
  };
  cudaEvent_t e0, e1, e2;
  WATERGS_CUDA_CHECK(cudaEventCreate(&e0));
  WATERGS_CUDA_CHECK(cudaEventCreate(&e1));
  WATERGS_CUDA_CHECK(cudaEventCreate(&e2));
  pass(e0, e1, e2);  // Warm-up: allocations, kernel loading.
  std::vector<double> forward, backward, both;
  for (int r = 0; r < std::max(repeats, 1); ++r) {
    pass(e0, e1, e2);
    float f = 0, b = 0;
    WATERGS_CUDA_CHECK(cudaEventElapsedTime(&f, e0, e1));
    WATERGS_CUDA_CHECK(cudaEventElapsedTime(&b, e1, e2));
    forward.push_back(f), backward.push_back(b), both.push_back(f + b);
  }
  cudaEventDestroy(e0), cudaEventDestroy(e1), cudaEventDestroy(e2);
  ResidentRasterTiming t;
  t.ok = true;
  t.forward_ms = Median(forward);
  t.backward_ms = Median(backward);
  t.both_ms = Median(both);
  return t;
}

}  // namespace watergs::bench
