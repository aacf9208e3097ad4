// Host side of the CUDA distortion layers (see cuda_distortion.h); kernels
// in distortion.cu.
#include "distortion/cuda/cuda_distortion.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "distortion/cuda/distortion_kernels.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

// distortion_layer.cc's RemovedCount.
size_t RemovedCount(size_t n, double fraction) {
  return std::min(n, static_cast<size_t>(std::llround(fraction * n)));
}

// Calls fn(in_buffer, out_buffer, stride) for each array of the model.
template <typename Fn>
void ForEachArray(const DeviceGaussianArrays& in, DeviceGaussianArrays* out,
                  Fn&& fn) {
  fn(in.means, &out->means, 3);
  fn(in.log_scales, &out->log_scales, 3);
  fn(in.quats, &out->quats, 4);
  fn(in.opacity_logits, &out->opacity_logits, 1);
  fn(in.sh_dc, &out->sh_dc, 3);
  fn(in.sh_rest, &out->sh_rest, in.sh_rest_stride());
}

}  // namespace

CudaDistortionLayer::CudaDistortionLayer(const DistortionSpec& spec)
    : spec_(spec) {
  MakeDistortionLayer(spec);  // validates the strength
}

void CudaDistortionLayer::Apply(const DeviceGaussianArrays& in,
                                std::mt19937_64& rng, DeviceGaussianArrays* out,
                                DeviceBuffer<uint32_t>* source) {
  if (&in == out) Fail("distortion (cuda): output aliases the input");
  const size_t n = in.size();
  if (n > std::numeric_limits<int32_t>::max()) {
    Fail("distortion (cuda): " + std::to_string(n) +
         " Gaussians exceed the 2^31 the device layers index");
  }
  size_t removed = 0;
  switch (spec_.kind) {
    case DistortionKind::kIdentity:
    case DistortionKind::kGaussianNoise:
      source->Resize(n);
      WATERGS_CUDA_CHECK(
          cuda_distortion::LaunchCropSource(n, 0, 0, source->data(), nullptr));
      break;
    case DistortionKind::kDropout: {
      removed = RemovedCount(n, spec_.strength);
      const uint64_t seed = rng();
      scratch_.Resize(cuda_distortion::DropoutScratchBytes(n));
      source->Resize(n - removed);
      WATERGS_CUDA_CHECK(cuda_distortion::LaunchDropoutSource(
          n, removed, seed, scratch_.data(), scratch_.size(), source->data(),
          nullptr));
      break;
    }
    case DistortionKind::kCrop: {
      // The CPU CropLayer's draw, so the same rng state crops the same run.
      removed = RemovedCount(n, spec_.strength);
      std::uniform_int_distribution<size_t> start_dist(0, n - removed);
      const size_t start = start_dist(rng);
      source->Resize(n - removed);
      WATERGS_CUDA_CHECK(cuda_distortion::LaunchCropSource(
          n, start, removed, source->data(), nullptr));
      break;
    }
  }
  const size_t n_out = n - removed;
  out->sh_degree = in.sh_degree;
  out->Resize(n_out);
  ForEachArray(
      in, out,
      [&](const DeviceBuffer<float>& from, DeviceBuffer<float>* to,
          int stride) {
        WATERGS_CUDA_CHECK(cuda_distortion::LaunchGatherRows(
            from.data(), source->data(), n_out, stride, to->data(), nullptr));
      });
  if (spec_.kind == DistortionKind::kGaussianNoise) {
    const uint64_t seed = rng();
    WATERGS_CUDA_CHECK(cuda_distortion::LaunchAddGaussianNoise(
        out->means.data(), out->means.size(),
        static_cast<float>(spec_.strength), seed, nullptr));
  }
}

void CudaDistortionLayer::Apply(const GaussianModel& in, std::mt19937_64& rng,
                                GaussianModel* out,
                                std::vector<uint32_t>* source) {
  in_stage_.Upload(in);
  Apply(in_stage_, rng, &out_stage_, &source_stage_);
  out_stage_.Download(out);
  source_stage_.Download(source);
}

void CudaScatterRows(const float* from, const DeviceBuffer<uint32_t>& source,
                     size_t n_from, int stride, float* to) {
  if (n_from > source.size()) {
    Fail("distortion (cuda): scatter of " + std::to_string(n_from) +
         " rows with " + std::to_string(source.size()) + " source entries");
  }
  WATERGS_CUDA_CHECK(cuda_distortion::LaunchScatterAddRows(
      from, source.data(), n_from, stride, to, nullptr));
}

void CudaScatterFlags(const uint8_t* from, const DeviceBuffer<uint32_t>& source,
                      size_t n_from, uint8_t* to) {
  if (n_from > source.size()) {
    Fail("distortion (cuda): scatter of " + std::to_string(n_from) +
         " flags with " + std::to_string(source.size()) + " source entries");
  }
  WATERGS_CUDA_CHECK(cuda_distortion::LaunchScatterOrFlags(
      from, source.data(), n_from, to, nullptr));
}

}  // namespace watergs
