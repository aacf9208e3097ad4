// The device buffers of the rasterizer's gradients for N Gaussians in the
// factored-SH layout (CudaGradientArrays with compact_sh), owned together so
// that the training step and the benchmarks size and hand them out in one
// call.
#pragma once

#include <cstddef>
#include <cstdint>

#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"

namespace watergs {

struct CompactGradientBuffers {
  // N x 3, N x 3, N x 4, N; dL/dcolour and the view direction, N x 3 each;
  // |dL/dmean2d| in pixels and in NDC units, N each; visibility, N.
  DeviceBuffer<float> means, log_scales, quats, opacity_logits, color, view_dir,
      norm, norm_ndc;
  DeviceBuffer<uint8_t> visible;

  // Sizes every buffer for n Gaussians; the rasterizer's view of them.
  CudaGradientArrays Resize(size_t n) {
    for (DeviceBuffer<float>* b : {&means, &log_scales, &color, &view_dir}) {
      b->Resize(3 * n);
    }
    quats.Resize(4 * n);
    for (DeviceBuffer<float>* b : {&opacity_logits, &norm, &norm_ndc}) {
      b->Resize(n);
    }
    visible.Resize(n);
    CudaGradientArrays g;
    g.means = means.data();
    g.log_scales = log_scales.data();
    g.quats = quats.data();
    g.opacity_logits = opacity_logits.data();
    g.compact_sh = true;
    g.sh_color_grad = color.data();
    g.sh_view_dir = view_dir.data();
    g.mean2d_grad_norm = norm.data();
    g.mean2d_grad_norm_ndc = norm_ndc.data();
    g.visible = visible.data();
    return g;
  }
};

}  // namespace watergs
