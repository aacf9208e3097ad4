// The CUDA rasterizer: runs the stages of raster_kernels.h (projection + SH
// colour, tile binning with a CUB radix sort, forward blending; reverse
// blending and the per-Gaussian backward) on device buffers that are reused
// from call to call, and keeps a forward pass's device state in its
// CudaRenderContext for the backward pass. The host entry points copy the
// model in and the image and gradients out; the device ones do not.
#include "gaussian/cuda/cuda_rasterizer.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/cuda/cuda_check.h"
#include "gaussian/cuda/cuda_device.h"
#include "gaussian/cuda/cuda_rasterizer_device.h"
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/cuda/raster_kernels.h"
#include "gaussian/projection.h"
#include "gaussian/render_conventions.h"
#include "gaussian/tile_binning.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace cuda_raster {

static_assert(sizeof(DeviceSplat) == 64, "a splat is one 64-byte load");
static_assert(kTile == kTileSize, "same tile grid as the CPU");

// A device buffer whose allocation grows by half again when it must grow,
// so a slowly growing model (densification) rarely reallocates.
template <typename T>
class Growable {
 public:
  // Sets the size to n elements; returns the device pointer.
  T* Fit(size_t n) {
    if (n > capacity_) {
      capacity_ = n + n / 2;
      buffer_.Resize(capacity_);
    }
    buffer_.Resize(n);
    return buffer_.data();
  }
  void Upload(const std::vector<T>& host) {
    Fit(host.size());
    buffer_.Upload(host);
  }
  void Download(std::vector<T>* host) const { buffer_.Download(host); }
  void Zero() { buffer_.Zero(); }
  T* data() { return buffer_.data(); }
  const T* data() const { return buffer_.data(); }

 private:
  // The allocation (its size is the logical size).
  DeviceBuffer<T> buffer_;
  // Elements allocated.
  size_t capacity_ = 0;
};

}  // namespace cuda_raster

using cuda_raster::DeviceCamera;
using cuda_raster::DeviceModel;
using cuda_raster::DeviceSplat;
using cuda_raster::DeviceSplatGrad;
using cuda_raster::Growable;
using cuda_raster::TileRect;

// Device memory of one forward pass and its backward pass. A workspace is
// reused by later passes once no context holds it.
struct CudaWorkspace {
  // Copy of a host model (Forward; ForwardDevice reads the caller's arrays).
  Growable<float> means, log_scales, quats, opacity_logits, sh_dc, sh_rest;
  // Per Gaussian: splat, binned tiles, depth, screen radius, tile count and
  // its inclusive prefix sum, colour-clamp bits, visibility.
  Growable<DeviceSplat> splats;
  Growable<TileRect> tiles;
  Growable<float> depth, radii;
  Growable<uint64_t> tile_counts, tile_offsets;
  Growable<uint8_t> clamped, visible;
  // (tile, depth) keys and Gaussian ids before and after the sort.
  Growable<uint64_t> keys, sorted_keys;
  Growable<uint32_t> ids, sorted_ids;
  // Per rendered tile: [first, end) of its sorted entries.
  Growable<uint32_t> tile_ranges;
  // CUB scratch (scan and sort).
  Growable<char> scratch;
  // Rendered image (Forward; rect, HWC) and per-pixel blend state.
  Growable<float> image, final_T;
  Growable<uint32_t> n_contrib;
  // Backward: dL/d(image) (Backward), per-Gaussian splat gradients, and the
  // gradient arrays Backward downloads.
  Growable<float> grad_image;
  Growable<DeviceSplatGrad> splat_grads;
  Growable<float> grad_means, grad_log_scales, grad_quats, grad_opacity;
  Growable<float> grad_sh_dc, grad_sh_rest, grad_color, grad_view_dir;
  Growable<float> grad_norm, grad_norm_ndc;
};

namespace {

// What a CUDA forward pass keeps for its backward pass.
class CudaRenderContext : public RenderContext {
 public:
  // Device state of the pass (splats, sorted lists, blend state).
  std::shared_ptr<CudaWorkspace> workspace;
  // The model's device arrays (the workspace's copy or the caller's).
  DeviceModel model{};
  // Camera, rendered rect and its tiles.
  DeviceCamera camera{};
  PixelRect rect;
  TileRect render_tiles{};
  // Full frame size (for the NDC gradient norm).
  int frame_width = 0, frame_height = 0;
  // SH degree the colours used.
  int active_sh_degree = 0;
  // Background the forward pass composited.
  std::array<float, 3> background = {0, 0, 0};
};

DeviceCamera ToDeviceCamera(const ProjectionCamera& c) {
  DeviceCamera d{};
  std::copy(c.R, c.R + 9, d.R);
  std::copy(c.t, c.t + 3, d.t);
  std::copy(c.center, c.center + 3, d.center);
  d.fx = c.fx, d.fy = c.fy, d.cx = c.cx, d.cy = c.cy;
  d.tan_fovx = c.tan_fovx, d.tan_fovy = c.tan_fovy;
  d.near_plane = c.near_plane, d.far_plane = c.far_plane;
  d.width = c.width, d.height = c.height;
  return d;
}

// Throws Error for an SH degree or a Gaussian count the kernels cannot take.
void CheckDegreeAndCount(int sh_degree, size_t n) {
  if (sh_degree < 0 || sh_degree > 3) {
    Fail("render: SH degree " + std::to_string(sh_degree) + " is outside 0-3");
  }
  if (n > static_cast<size_t>(INT_MAX)) {
    Fail("render: " + std::to_string(n) +
         " Gaussians exceed the CUDA rasterizer's limit of 2^31 - 1");
  }
}

// Throws Error unless every array has the model's Gaussian count (the GPU
// would read out of bounds where the CPU code would only misbehave).
void CheckModel(const GaussianModel& model) {
  const size_t n = model.size();
  CheckDegreeAndCount(model.sh_degree, n);
  const size_t stride = static_cast<size_t>(model.sh_rest_stride());
  if (model.means.size() != 3 * n || model.log_scales.size() != 3 * n ||
      model.quats.size() != 4 * n || model.sh_dc.size() != 3 * n ||
      model.sh_rest.size() != n * stride) {
    Fail("render: model arrays do not all hold " + std::to_string(n) +
         " Gaussians of SH degree " + std::to_string(model.sh_degree));
  }
}

// A context for rendering `camera` / `options` with a model of `sh_degree`;
// its workspace and model are set by the caller.
std::unique_ptr<CudaRenderContext> NewContext(const RenderCamera& camera,
                                              const RenderOptions& options,
                                              int sh_degree) {
  RequireDefaultConventions(options.conventions, "the CUDA rasterizer");
  const PixelRect rect = ResolveRenderRect(camera, options);
  auto ctx = std::make_unique<CudaRenderContext>();
  ctx->camera = ToDeviceCamera(MakeProjectionCamera(camera));
  ctx->rect = rect;
  const TileRange tiles =
      TilesCoveringRect(rect.x0, rect.y0, rect.width, rect.height);
  ctx->render_tiles = TileRect{tiles.x0, tiles.y0, tiles.x1, tiles.y1};
  ctx->frame_width = camera.width, ctx->frame_height = camera.height;
  ctx->active_sh_degree = options.active_sh_degree < 0
                              ? sh_degree
                              : std::min(options.active_sh_degree, sh_degree);
  ctx->background = options.background;
  return ctx;
}

size_t RectPixels(const PixelRect& rect) {
  return static_cast<size_t>(rect.width) * static_cast<size_t>(rect.height);
}

// Projection and binning: fills the workspace's splats, sorted ids and tile
// ranges for ctx's model, camera and rect.
void ProjectAndBin(const CudaRenderContext& ctx, CudaWorkspace* ws) {
  const int n = ctx.model.count;
  const TileRect& rt = ctx.render_tiles;
  const int num_tiles = (rt.x1 - rt.x0) * (rt.y1 - rt.y0);
  cuda_raster::ProjectionOutputs out{ws->splats.Fit(n),  ws->tiles.Fit(n),
                                     ws->depth.Fit(n),   ws->tile_counts.Fit(n),
                                     ws->clamped.Fit(n), ws->visible.Fit(n),
                                     ws->radii.Fit(n)};
  ws->tile_offsets.Fit(n);
  cuda_raster::LaunchProject(ctx.model, ctx.camera, ctx.active_sh_degree, rt,
                             out);
  uint64_t entries = 0;
  if (n > 0) {
    const size_t bytes = cuda_raster::ScanScratchBytes(n);
    cuda_raster::LaunchScanTileCounts(ws->tile_counts.data(),
                                      ws->tile_offsets.data(), n,
                                      ws->scratch.Fit(bytes), bytes);
    WATERGS_CUDA_CHECK(cudaMemcpy(&entries, ws->tile_offsets.data() + n - 1,
                                  sizeof(entries), cudaMemcpyDeviceToHost));
  }
  if (entries > UINT32_MAX) {
    Fail("render: " + std::to_string(entries) +
         " Gaussian-tile pairs exceed the CUDA rasterizer's limit of 2^32");
  }
  cuda_raster::LaunchDuplicateKeys(
      n, ws->tiles.data(), ws->depth.data(), ws->tile_counts.data(),
      ws->tile_offsets.data(), rt, ws->keys.Fit(entries), ws->ids.Fit(entries));
  const int key_bits = cuda_raster::SortKeyBits(num_tiles);
  const size_t sort_bytes = cuda_raster::SortScratchBytes(entries, key_bits);
  cuda_raster::LaunchSortPairs(ws->keys.data(), ws->sorted_keys.Fit(entries),
                               ws->ids.data(), ws->sorted_ids.Fit(entries),
                               entries, key_bits, ws->scratch.Fit(sort_bytes),
                               sort_bytes);
  ws->tile_ranges.Fit(2 * static_cast<size_t>(num_tiles));
  ws->tile_ranges.Zero();
  cuda_raster::LaunchTileRanges(ws->sorted_keys.data(), entries,
                                ws->tile_ranges.data());
}

// Projects, bins and blends ctx's model into `image` (device, rect HWC).
void RenderContextInto(const CudaRenderContext& ctx, float* image) {
  CudaWorkspace& ws = *ctx.workspace;
  ProjectAndBin(ctx, &ws);
  const PixelRect& rect = ctx.rect;
  const size_t pixels = RectPixels(rect);
  cuda_raster::LaunchRasterizeForward(
      ws.splats.data(), ws.sorted_ids.data(), ws.tile_ranges.data(),
      ctx.render_tiles, {rect.x0, rect.y0, rect.width, rect.height},
      ctx.background.data(), image, ws.final_T.Fit(pixels),
      ws.n_contrib.Fit(pixels));
}

const CudaRenderContext& AsCudaContext(const RenderContext& context) {
  const auto* ctx = dynamic_cast<const CudaRenderContext*>(&context);
  if (ctx == nullptr) {
    Fail("render backward: the context does not come from a CUDA forward pass");
  }
  return *ctx;
}

// Reverse blending and the per-Gaussian backward of ctx's pass:
// grad_image (device, rect HWC) to the device arrays `out`.
void BackwardInto(const CudaRenderContext& ctx, const float* grad_image,
                  const cuda_raster::GradientOutputs& out) {
  CudaWorkspace& ws = *ctx.workspace;
  const PixelRect& rect = ctx.rect;
  ws.splat_grads.Fit(static_cast<size_t>(ctx.model.count));
  ws.splat_grads.Zero();
  cuda_raster::LaunchRasterizeBackward(
      ws.splats.data(), ws.sorted_ids.data(), ws.tile_ranges.data(),
      ctx.render_tiles, {rect.x0, rect.y0, rect.width, rect.height},
      ctx.background.data(), ws.final_T.data(), ws.n_contrib.data(), grad_image,
      ws.splat_grads.data());
  cuda_raster::LaunchGaussianBackward(
      ctx.model, ctx.camera, ctx.active_sh_degree, ctx.frame_width,
      ctx.frame_height, ws.tile_counts.data(), ws.clamped.data(),
      ws.splat_grads.data(), out);
}

}  // namespace

CudaRasterizer::CudaRasterizer() {
  std::string why;
  if (!CudaDeviceVisible(&why)) Fail("--device cuda: " + why);
}

CudaRasterizer::~CudaRasterizer() = default;

std::shared_ptr<CudaWorkspace> CudaRasterizer::AcquireWorkspace() {
  for (const auto& workspace : pool_) {
    if (workspace.use_count() == 1) return workspace;
  }
  auto workspace = std::make_shared<CudaWorkspace>();
  if (pool_.size() < 2) pool_.push_back(workspace);
  return workspace;
}

void CudaRasterizer::Forward(const GaussianModel& model,
                             const RenderCamera& camera,
                             const RenderOptions& options, ImageRGB* image,
                             std::unique_ptr<RenderContext>* context) {
  CheckModel(model);
  auto ctx = NewContext(camera, options, model.sh_degree);
  ctx->workspace = AcquireWorkspace();
  CudaWorkspace& ws = *ctx->workspace;
  ws.means.Upload(model.means);
  ws.log_scales.Upload(model.log_scales);
  ws.quats.Upload(model.quats);
  ws.opacity_logits.Upload(model.opacity_logits);
  ws.sh_dc.Upload(model.sh_dc);
  ws.sh_rest.Upload(model.sh_rest);
  ctx->model =
      DeviceModel{ws.means.data(),        ws.log_scales.data(),
                  ws.quats.data(),        ws.opacity_logits.data(),
                  ws.sh_dc.data(),        ws.sh_rest.data(),
                  model.sh_rest_stride(), static_cast<int>(model.size())};
  RenderContextInto(*ctx, ws.image.Fit(3 * RectPixels(ctx->rect)));
  *image = ImageRGB();
  image->width = ctx->rect.width, image->height = ctx->rect.height;
  ws.image.Download(&image->data);
  if (context != nullptr) *context = std::move(ctx);
}

void CudaRasterizer::ForwardDevice(const CudaModelArrays& model,
                                   const RenderCamera& camera,
                                   const RenderOptions& options, float* image,
                                   std::unique_ptr<RenderContext>* context) {
  CheckDegreeAndCount(model.sh_degree, model.count);
  const bool has_rest = model.sh_degree > 0;
  if (model.count > 0 &&
      (!model.means || !model.log_scales || !model.quats ||
       !model.opacity_logits || !model.sh_dc || (has_rest && !model.sh_rest))) {
    Fail("render: a device model array is null");
  }
  auto ctx = NewContext(camera, options, model.sh_degree);
  // The rect is never empty, so the kernels write the image.
  if (image == nullptr) Fail("render: the device image array is null");
  ctx->workspace = AcquireWorkspace();
  ctx->model = DeviceModel{model.means,
                           model.log_scales,
                           model.quats,
                           model.opacity_logits,
                           model.sh_dc,
                           model.sh_rest,
                           3 * (NumShCoeffs(model.sh_degree) - 1),
                           static_cast<int>(model.count)};
  RenderContextInto(*ctx, image);
  if (context != nullptr) *context = std::move(ctx);
}

void CudaRasterizer::Backward(const GaussianModel& model,
                              const RenderContext& context,
                              const ImageRGB& grad_image,
                              GaussianGradients* grads) {
  const CudaRenderContext& ctx = AsCudaContext(context);
  const PixelRect& rect = ctx.rect;
  if (grad_image.width != rect.width || grad_image.height != rect.height ||
      grad_image.data.size() != 3 * RectPixels(rect) ||
      model.size() != static_cast<size_t>(ctx.model.count) ||
      model.sh_rest_stride() != ctx.model.rest_stride) {
    Fail(
        "render backward: gradient image or model does not match the "
        "forward pass");
  }
  CudaWorkspace& ws = *ctx.workspace;
  ws.grad_image.Upload(grad_image.data);
  const bool compact = grads->compact_sh;
  const size_t n = model.size();
  const size_t stride = static_cast<size_t>(ctx.model.rest_stride);
  cuda_raster::GradientOutputs out{
      ws.grad_means.Fit(3 * n),
      ws.grad_log_scales.Fit(3 * n),
      ws.grad_quats.Fit(4 * n),
      ws.grad_opacity.Fit(n),
      ws.grad_sh_dc.Fit(compact ? 0 : 3 * n),
      ws.grad_sh_rest.Fit(compact ? 0 : n * stride),
      ws.grad_color.Fit(compact ? 3 * n : 0),
      ws.grad_view_dir.Fit(compact ? 3 * n : 0),
      ws.grad_norm.Fit(n),
      ws.grad_norm_ndc.Fit(n),
      compact};
  BackwardInto(ctx, ws.grad_image.data(), out);
  ws.grad_means.Download(&grads->means);
  ws.grad_log_scales.Download(&grads->log_scales);
  ws.grad_quats.Download(&grads->quats);
  ws.grad_opacity.Download(&grads->opacity_logits);
  ws.grad_sh_dc.Download(&grads->sh_dc);
  ws.grad_sh_rest.Download(&grads->sh_rest);
  ws.grad_color.Download(&grads->sh_color_grad);
  ws.grad_view_dir.Download(&grads->sh_view_dir);
  ws.grad_norm.Download(&grads->mean2d_grad_norm);
  ws.grad_norm_ndc.Download(&grads->mean2d_grad_norm_ndc);
  ws.visible.Download(&grads->visible);
  grads->sh_active_degree = ctx.active_sh_degree;
}

void CudaRasterizer::BackwardDevice(const RenderContext& context,
                                    const float* grad_image,
                                    const CudaGradientArrays& grads) {
  const CudaRenderContext& ctx = AsCudaContext(context);
  const bool dense_sh_ok =
      grads.sh_dc && (grads.sh_rest || ctx.model.rest_stride == 0);
  const bool sh_ok =
      grads.compact_sh ? grads.sh_color_grad && grads.sh_view_dir : dense_sh_ok;
  if (ctx.model.count > 0 &&
      (!grads.means || !grads.log_scales || !grads.quats ||
       !grads.opacity_logits || !grads.mean2d_grad_norm ||
       !grads.mean2d_grad_norm_ndc || !sh_ok ||
       (ctx.rect.width > 0 && !grad_image))) {
    Fail("render backward: a device gradient array is null");
  }
  const cuda_raster::GradientOutputs out{grads.means,
                                         grads.log_scales,
                                         grads.quats,
                                         grads.opacity_logits,
                                         grads.sh_dc,
                                         grads.sh_rest,
                                         grads.sh_color_grad,
                                         grads.sh_view_dir,
                                         grads.mean2d_grad_norm,
                                         grads.mean2d_grad_norm_ndc,
                                         grads.compact_sh};
  BackwardInto(ctx, grad_image, out);
  const size_t n = static_cast<size_t>(ctx.model.count);
  if (grads.visible != nullptr && n > 0) {
    WATERGS_CUDA_CHECK(cudaMemcpy(grads.visible, ctx.workspace->visible.data(),
                                  n, cudaMemcpyDeviceToDevice));
  }
}

void CudaRasterizer::DownloadScreenRadii(const RenderContext& context,
                                         std::vector<float>* radii) const {
  const CudaRenderContext& ctx = AsCudaContext(context);
  ctx.workspace->radii.Download(radii);
  radii->resize(static_cast<size_t>(ctx.model.count));
}

const float* CudaRasterizer::DeviceScreenRadii(
    const RenderContext& context) const {
  return AsCudaContext(context).workspace->radii.data();
}

std::unique_ptr<Rasterizer> MakeCudaRasterizer() {
  return std::make_unique<CudaRasterizer>();
}

}  // namespace watergs
