// The 3D distortion layers N(Θ) of WATER-GS (distortion_layer.h) on a CUDA
// device: Gaussian noise on the positions, dropout and crop of the point
// set, with the CPU layers' semantics. Crop and Identity draw from the rng
// exactly as the CPU layers do, so they give the CPU's result bit for bit;
// noise and dropout take one 64-bit seed from the rng and a counter-based
// device stream, so their samples differ from the CPU's (same
// distribution: N(0, sigma^2) per coordinate; exactly round(p N) Gaussians
// removed, a uniformly random subset, file order kept).
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "distortion/distortion_layer.h"
#include "gaussian/cuda/cuda_model_mirror.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

class CudaDistortionLayer {
 public:
  // Throws Error for strengths out of range, as MakeDistortionLayer.
  explicit CudaDistortionLayer(const DistortionSpec& spec);

  // True if Apply returns the input unchanged.
  bool IsIdentity() const { return spec_.kind == DistortionKind::kIdentity; }
  const DistortionSpec& spec() const { return spec_; }

  // out = N(in) on the device; source (device, out->size() entries) gets the
  // index in `in` of each output Gaussian. `out` must not alias `in`.
  void Apply(const DeviceGaussianArrays& in, std::mt19937_64& rng,
             DeviceGaussianArrays* out, DeviceBuffer<uint32_t>* source);
  // DistortionLayer::Apply's contract on host models (copies both ways).
  void Apply(const GaussianModel& in, std::mt19937_64& rng, GaussianModel* out,
             std::vector<uint32_t>* source);

 private:
  DistortionSpec spec_;
  // Dropout's key sort and compaction space.
  DeviceBuffer<unsigned char> scratch_;
  // Device copies for the host Apply.
  DeviceGaussianArrays in_stage_, out_stage_;
  DeviceBuffer<uint32_t> source_stage_;
};

// ScatterGradients' row scatter on the device: row source[i] of `to` (the
// undistorted model's gradient, n_in rows, already zeroed or accumulating)
// += row i of `from`, i < n_from, stride floats per row.
void CudaScatterRows(const float* from, const DeviceBuffer<uint32_t>& source,
                     size_t n_from, int stride, float* to);

// The visibility flags' scatter: to[source[i]] |= from[i], i < n_from
// (device arrays; `to` holds the undistorted model's N flags).
void CudaScatterFlags(const uint8_t* from, const DeviceBuffer<uint32_t>& source,
                      size_t n_from, uint8_t* to);

}  // namespace watergs
