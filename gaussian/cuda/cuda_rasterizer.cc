// The CUDA rasterizer: uploads the model, runs the stages of raster_kernels.h
// (projection + SH colour, tile binning with a CUB radix sort, forward
// blending; reverse blending and the per-Gaussian backward) on device
// buffers that are reused from call to call, and keeps a forward pass's
// device state in its CudaRenderContext for the backward pass.
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
#include "gaussian/cuda/device_buffer.h"
#include "gaussian/cuda/raster_kernels.h"
#include "gaussian/error.h"
#include "gaussian/projection.h"
#include "gaussian/tile_binning.h"

namespace watergs {
namespace {

using cuda_raster::DeviceCamera;
using cuda_raster::DeviceModel;
using cuda_raster::DeviceSplat;
using cuda_raster::DeviceSplatGrad;
using cuda_raster::TileRect;

static_assert(sizeof(DeviceSplat) == 64, "a splat is one 64-byte load");
static_assert(cuda_raster::kTile == kTileSize, "same tile grid as the CPU");

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

// Device memory of one forward pass and its backward pass. A workspace is
// reused by later passes once no context holds it.
struct CudaWorkspace {
  // The model as rendered (GaussianModel arrays).
  Growable<float> means, log_scales, quats, opacity_logits, sh_dc, sh_rest;
  // Per Gaussian: splat, binned tiles, depth, tile count and its inclusive
  // prefix sum, colour-clamp bits, visibility.
  Growable<DeviceSplat> splats;
  Growable<TileRect> tiles;
  Growable<float> depth;
  Growable<uint64_t> tile_counts, tile_offsets;
  Growable<uint8_t> clamped, visible;
  // (tile, depth) keys and Gaussian ids before and after the sort.
  Growable<uint64_t> keys, sorted_keys;
  Growable<uint32_t> ids, sorted_ids;
  // Per rendered tile: [first, end) of its sorted entries.
  Growable<uint32_t> tile_ranges;
  // CUB scratch (scan and sort).
  Growable<char> scratch;
  // Rendered image (rect, HWC) and per-pixel blend state.
  Growable<float> image, final_T;
  Growable<uint32_t> n_contrib;
  // Backward: dL/d(image), per-Gaussian splat gradients and the outputs.
  Growable<float> grad_image;
  Growable<DeviceSplatGrad> splat_grads;
  Growable<float> grad_means, grad_log_scales, grad_quats, grad_opacity;
  Growable<float> grad_sh_dc, grad_sh_rest, grad_color, grad_view_dir;
  Growable<float> grad_norm, grad_norm_ndc;
};

// What a CUDA forward pass keeps for its backward pass.
class CudaRenderContext : public RenderContext {
 public:
  // Device state of the pass (model copy, splats, sorted lists, blend state).
  std::shared_ptr<CudaWorkspace> workspace;
  // Camera, rendered rect and its tiles.
  DeviceCamera camera{};
  PixelRect rect;
  TileRect render_tiles{};
  // Full frame size (for the NDC gradient norm).
  int frame_width = 0, frame_height = 0;
  // SH degree the colours used, and the model's sh_rest stride.
  int active_sh_degree = 0, rest_stride = 0;
  // Background the forward pass composited.
  std::array<float, 3> background = {0, 0, 0};
  // Number of Gaussians in the model rendered.
  size_t num_gaussians = 0;
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

// Throws Error unless every array has the model's Gaussian count (the GPU
// would read out of bounds where the CPU code would only misbehave).
void CheckModel(const GaussianModel& model) {
  const size_t n = model.size();
  if (model.sh_degree < 0 || model.sh_degree > 3 ||
      model.means.size() != 3 * n || model.log_scales.size() != 3 * n ||
      model.quats.size() != 4 * n || model.sh_dc.size() != 3 * n ||
      model.sh_rest.size() != n * model.sh_rest_stride()) {
    Fail("render: model arrays do not all hold " + std::to_string(n) +
         " Gaussians of SH degree " + std::to_string(model.sh_degree));
  }
  if (n > static_cast<size_t>(INT_MAX)) {
    Fail("render: " + std::to_string(n) +
         " Gaussians exceed the CUDA rasterizer's limit of 2^31 - 1");
  }
}

DeviceModel ModelView(CudaWorkspace& ws, int count, int rest_stride) {
  return DeviceModel{ws.means.data(), ws.log_scales.data(),
                     ws.quats.data(), ws.opacity_logits.data(),
                     ws.sh_dc.data(), ws.sh_rest.data(),
                     rest_stride,     count};
}

void UploadModel(const GaussianModel& model, CudaWorkspace* ws) {
  ws->means.Upload(model.means);
  ws->log_scales.Upload(model.log_scales);
  ws->quats.Upload(model.quats);
  ws->opacity_logits.Upload(model.opacity_logits);
  ws->sh_dc.Upload(model.sh_dc);
  ws->sh_rest.Upload(model.sh_rest);
}

// Projection and binning: fills the workspace's splats, sorted ids and tile
// ranges for ctx's camera and rect.
void ProjectAndBin(const CudaRenderContext& ctx, CudaWorkspace* ws) {
  const int n = static_cast<int>(ctx.num_gaussians);
  const TileRect& rt = ctx.render_tiles;
  const int num_tiles = (rt.x1 - rt.x0) * (rt.y1 - rt.y0);
  cuda_raster::ProjectionOutputs out{ws->splats.Fit(n),  ws->tiles.Fit(n),
                                     ws->depth.Fit(n),   ws->tile_counts.Fit(n),
                                     ws->clamped.Fit(n), ws->visible.Fit(n)};
  ws->tile_offsets.Fit(n);
  cuda_raster::LaunchProject(ModelView(*ws, n, ctx.rest_stride), ctx.camera,
                             ctx.active_sh_degree, rt, out);
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

class CudaRasterizer : public Rasterizer {
 public:
  void Forward(const GaussianModel& model, const RenderCamera& camera,
               const RenderOptions& options, ImageRGB* image,
               std::unique_ptr<RenderContext>* context) override;
  void Backward(const GaussianModel& model, const RenderContext& context,
                const ImageRGB& grad_image, GaussianGradients* grads) override;

 private:
  // A pooled workspace no live context holds, or a new one.
  std::shared_ptr<CudaWorkspace> AcquireWorkspace();

  // Workspaces kept for reuse: two cover a caller that keeps the previous
  // context alive while rendering the next view.
  static constexpr size_t kMaxPooled = 2;
  std::vector<std::shared_ptr<CudaWorkspace>> pool_;
};

std::shared_ptr<CudaWorkspace> CudaRasterizer::AcquireWorkspace() {
  for (const auto& workspace : pool_) {
    if (workspace.use_count() == 1) return workspace;
  }
  auto workspace = std::make_shared<CudaWorkspace>();
  if (pool_.size() < kMaxPooled) pool_.push_back(workspace);
  return workspace;
}

void CudaRasterizer::Forward(const GaussianModel& model,
                             const RenderCamera& camera,
                             const RenderOptions& options, ImageRGB* image,
                             std::unique_ptr<RenderContext>* context) {
  const PixelRect rect = ResolveRenderRect(camera, options);
  CheckModel(model);
  auto ctx = std::make_unique<CudaRenderContext>();
  ctx->workspace = AcquireWorkspace();
  CudaWorkspace& ws = *ctx->workspace;
  ctx->camera = ToDeviceCamera(MakeProjectionCamera(camera));
  ctx->rect = rect;
  const TileRange tiles =
      TilesCoveringRect(rect.x0, rect.y0, rect.width, rect.height);
  ctx->render_tiles = TileRect{tiles.x0, tiles.y0, tiles.x1, tiles.y1};
  ctx->frame_width = camera.width, ctx->frame_height = camera.height;
  ctx->active_sh_degree =
      options.active_sh_degree < 0
          ? model.sh_degree
          : std::min(options.active_sh_degree, model.sh_degree);
  ctx->rest_stride = model.sh_rest_stride();
  ctx->background = options.background;
  ctx->num_gaussians = model.size();
  UploadModel(model, &ws);
  ProjectAndBin(*ctx, &ws);
  const size_t pixels = static_cast<size_t>(rect.width) * rect.height;
  cuda_raster::LaunchRasterizeForward(
      ws.splats.data(), ws.sorted_ids.data(), ws.tile_ranges.data(),
      ctx->render_tiles, {rect.x0, rect.y0, rect.width, rect.height},
      options.background.data(), ws.image.Fit(3 * pixels),
      ws.final_T.Fit(pixels), ws.n_contrib.Fit(pixels));
  *image = ImageRGB();
  image->width = rect.width, image->height = rect.height;
  ws.image.Download(&image->data);
  if (context != nullptr) *context = std::move(ctx);
}

void CudaRasterizer::Backward(const GaussianModel& model,
                              const RenderContext& context,
                              const ImageRGB& grad_image,
                              GaussianGradients* grads) {
  const auto* ctx = dynamic_cast<const CudaRenderContext*>(&context);
  if (ctx == nullptr) {
    Fail("render backward: the context does not come from a CUDA forward pass");
  }
  const PixelRect& rect = ctx->rect;
  if (grad_image.width != rect.width || grad_image.height != rect.height ||
      grad_image.data.size() != 3 * static_cast<size_t>(rect.width) *
                                    static_cast<size_t>(rect.height) ||
      model.size() != ctx->num_gaussians ||
      model.sh_rest_stride() != ctx->rest_stride) {
    Fail(
        "render backward: gradient image or model does not match the "
        "forward pass");
  }
  CudaWorkspace& ws = *ctx->workspace;
  const int n = static_cast<int>(ctx->num_gaussians);
  ws.grad_image.Upload(grad_image.data);
  ws.splat_grads.Fit(n);
  ws.splat_grads.Zero();
  cuda_raster::LaunchRasterizeBackward(
      ws.splats.data(), ws.sorted_ids.data(), ws.tile_ranges.data(),
      ctx->render_tiles, {rect.x0, rect.y0, rect.width, rect.height},
      ctx->background.data(), ws.final_T.data(), ws.n_contrib.data(),
      ws.grad_image.data(), ws.splat_grads.data());
  const bool compact = grads->compact_sh;
  const size_t un = static_cast<size_t>(n);
  cuda_raster::GradientOutputs out{
      ws.grad_means.Fit(3 * un),
      ws.grad_log_scales.Fit(3 * un),
      ws.grad_quats.Fit(4 * un),
      ws.grad_opacity.Fit(un),
      ws.grad_sh_dc.Fit(compact ? 0 : 3 * un),
      ws.grad_sh_rest.Fit(compact ? 0 : un * ctx->rest_stride),
      ws.grad_color.Fit(compact ? 3 * un : 0),
      ws.grad_view_dir.Fit(compact ? 3 * un : 0),
      ws.grad_norm.Fit(un),
      ws.grad_norm_ndc.Fit(un),
      compact};
  cuda_raster::LaunchGaussianBackward(
      ModelView(ws, n, ctx->rest_stride), ctx->camera, ctx->active_sh_degree,
      ctx->frame_width, ctx->frame_height, ws.tile_counts.data(),
      ws.clamped.data(), ws.splat_grads.data(), out);
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
  grads->sh_active_degree = ctx->active_sh_degree;
}

}  // namespace

std::unique_ptr<Rasterizer> MakeCudaRasterizer() {
  std::string why;
  if (!CudaDeviceVisible(&why)) Fail("--device cuda: " + why);
  return std::make_unique<CudaRasterizer>();
}

}  // namespace watergs
