// Launch API of the CUDA rasterizer stages (projection.cu, tile_binning.cu,
// rasterize_forward.cu, rasterize_backward.cu): plain C++17 structs and
// functions on raw device pointers, so nvcc and the C++20 host code
// (cuda_rasterizer.cc) share it. Each stage mirrors its CPU twin
// (projection.cc, tile_binning.cc, rasterize_forward.cc,
// rasterize_backward.cc) formula for formula.
#pragma once

#include <cstddef>
#include <cstdint>

namespace watergs::cuda_raster {

// Side of a square screen tile in pixels (kTileSize of projection.h).
inline constexpr int kTile = 16;
// Splats one thread block stages in shared memory per batch (one per thread).
inline constexpr int kBatch = kTile * kTile;

// Camera quantities in double, field for field ProjectionCamera.
struct DeviceCamera {
  // World-to-camera rotation (row-major) and translation.
  double R[9], t[3];
  // Pinhole intrinsics in pixels (COLMAP convention).
  double fx, fy, cx, cy;
  // tan of the half field of view.
  double tan_fovx, tan_fovy;
  // Depth culling range.
  double near_plane, far_plane;
  // Camera centre in world coordinates (SH view directions).
  double center[3];
  // Full frame size in pixels.
  int width, height;
};

// Tiles [x0, x1) x [y0, y1) of the full frame's grid (TileRange).
struct TileRect {
  int x0, y0, x1, y1;
};

// Pixels [x0, x0 + width) x [y0, y0 + height) of the full frame (PixelRect).
struct PixelBox {
  int x0, y0, width, height;
};

// One projected Gaussian as the blending kernels read it: the CPU Splat's
// fields (rasterize_forward.h) in the same order, 64 bytes (16-byte aligned:
// the blending kernels copy it with four 128-bit loads).
struct alignas(16) DeviceSplat {
  // Pixel-space mean (COLMAP convention).
  float mean_x, mean_y;
  // Conic (a, b, c): power = -0.5 (a dx^2 + c dy^2) - b dx dy.
  float conic_a, conic_b, conic_c;
  // Opacity after the sigmoid.
  float opacity;
  // Clamped colour.
  float color[3];
  // Rows (full frame) where alpha can reach 1/255.
  int row_min, row_max;
  // Row-interval bound of the alpha support (see Splat::shear).
  float shear, reach, narrowing;
  // Padding to 64 bytes.
  float pad[2];
};

// Gradient of one splat's blending inputs (SplatGrad), summed over pixels.
struct DeviceSplatGrad {
  // dL/d(pixel-space mean).
  float mean_x, mean_y;
  // dL/d(conic a, b, c).
  float conic_a, conic_b, conic_c;
  // dL/d(opacity after the sigmoid).
  float opacity;
  // dL/d(clamped colour).
  float color[3];
};

// The model's arrays on the device (GaussianModel layout).
struct DeviceModel {
  // N x 3, N x 3, N x 4, N, N x 3, N x rest_stride.
  const float *means, *log_scales, *quats, *opacity_logits, *sh_dc, *sh_rest;
  // Floats of sh_rest per Gaussian.
  int rest_stride;
  // Number of Gaussians N.
  int count;
};

// Per-Gaussian outputs of the projection stage (indexed by Gaussian id).
struct ProjectionOutputs {
  // Blending parameters (valid where tile_counts > 0).
  DeviceSplat* splats;
  // Tiles to bin into, already cut to the rendered tiles and the support.
  TileRect* tiles;
  // Camera depth (sort key).
  float* depth;
  // Number of tiles in `tiles` (0: not binned).
  uint64_t* tile_counts;
  // Bit c: colour channel c was clamped at 0.
  uint8_t* clamped;
  // 1 if visible (Inria's radius > 0 and its tiles meet the rendered ones).
  uint8_t* visible;
  // Inria's 3-sigma screen radius in pixels where visible, else 0
  // (ComputeScreenRadii of projection.h); may be null.
  float* radii;
};

// Per-Gaussian gradient arrays (GaussianGradients layout) on the device.
struct GradientOutputs {
  // N x 3, N x 3, N x 4, N.
  float *means, *log_scales, *quats, *opacity_logits;
  // Dense SH gradients (N x 3, N x rest_stride); unused when compact.
  float *sh_dc, *sh_rest;
  // Compact SH gradients (N x 3 each); unused when not compact.
  float *sh_color_grad, *sh_view_dir;
  // N each: |dL/dmean2d| in pixels and in NDC units.
  float *mean2d_grad_norm, *mean2d_grad_norm_ndc;
  // Store the SH gradients in factored form.
  bool compact;
};

// Projects, culls and shades every Gaussian for the tiles `render_tiles`
// (ProjectModel of cpu_rasterizer.cc). Writes every entry of `out`.
void LaunchProject(const DeviceModel& model, const DeviceCamera& camera,
                   int active_sh_degree, TileRect render_tiles,
                   ProjectionOutputs out);

// Scratch bytes that LaunchScanTileCounts needs for n Gaussians.
size_t ScanScratchBytes(int n);
// offsets[i] = counts[0] + ... + counts[i] (inclusive prefix sum, CUB).
void LaunchScanTileCounts(const uint64_t* counts, uint64_t* offsets, int n,
                          void* scratch, size_t scratch_bytes);

// Writes one (key, Gaussian id) pair per (Gaussian, tile): key = tile index
// in `render_tiles` (row-major) << 32 | order-preserving bits of the depth.
// Gaussian i writes positions [offsets[i] - counts[i], offsets[i]).
void LaunchDuplicateKeys(int n, const TileRect* tiles, const float* depth,
                         const uint64_t* counts, const uint64_t* offsets,
                         TileRect render_tiles, uint64_t* keys, uint32_t* ids);

// Bits of the sort key that can be non-zero for `num_tiles` tiles.
int SortKeyBits(int num_tiles);
// Scratch bytes of LaunchSortPairs for `entries` pairs.
size_t SortScratchBytes(size_t entries, int key_bits);
// Stable CUB radix sort of (key, id) pairs on the low `key_bits` key bits.
void LaunchSortPairs(const uint64_t* keys_in, uint64_t* keys_out,
                     const uint32_t* ids_in, uint32_t* ids_out, size_t entries,
                     int key_bits, void* scratch, size_t scratch_bytes);

// ranges[2 t], ranges[2 t + 1]: first and one-past-last sorted entry of
// tile t; `ranges` must be zeroed before (empty tiles stay [0, 0)).
void LaunchTileRanges(const uint64_t* sorted_keys, size_t entries,
                      uint32_t* ranges);

// Blends each tile's depth-ordered list into `rect` (one 16 x 16 block per
// tile of `render_tiles`). image: rect.height x rect.width x 3; final_T and
// n_contrib (1 + list position of the last contributor): one per pixel.
// background: host array of 3 floats (passed to the kernel by value).
void LaunchRasterizeForward(const DeviceSplat* splats,
                            const uint32_t* sorted_ids, const uint32_t* ranges,
                            TileRect render_tiles, PixelBox rect,
                            const float* background, float* image,
                            float* final_T, uint32_t* n_contrib);

// Reverse walk per pixel (RasterizeBackward): adds each pixel's gradient
// into splat_grads[Gaussian id] (zeroed before) with atomicAdd.
void LaunchRasterizeBackward(const DeviceSplat* splats,
                             const uint32_t* sorted_ids, const uint32_t* ranges,
                             TileRect render_tiles, PixelBox rect,
                             const float* background, const float* final_T,
                             const uint32_t* n_contrib, const float* grad_image,
                             DeviceSplatGrad* splat_grads);

// Per-Gaussian backward through SH, the sigmoid and the projection
// (GaussianBackward of cpu_rasterizer.cc): writes every entry of `out`.
// frame_width/height: the full frame (for the NDC gradient norm).
void LaunchGaussianBackward(const DeviceModel& model,
                            const DeviceCamera& camera, int active_sh_degree,
                            int frame_width, int frame_height,
                            const uint64_t* tile_counts, const uint8_t* clamped,
                            const DeviceSplatGrad* splat_grads,
                            GradientOutputs out);

}  // namespace watergs::cuda_raster
