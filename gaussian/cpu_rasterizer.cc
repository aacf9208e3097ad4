// CPU rasterizer: wires projection, SH colour, depth sort, binning and the
// blending passes; the per-Gaussian stages run in parallel over Gaussians.
#include "gaussian/cpu_rasterizer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "gaussian/sh.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// Rows and tiles where a splat's alpha can reach 1/255: the ellipse
// d^T conic d <= 2 ln(255 opacity), bounded via the covariance diagonal.
// Returns false if the splat can never reach 1/255.
bool AlphaSupport(const ProjectedGaussian& p, float opacity, Splat* s,
                  TileRange* tiles) {
  const double level = std::log(255.0 * static_cast<double>(opacity));
  if (!(level > 0)) return false;
  // Margin covers float rounding in the blending loops.
  auto half = [&](double var) {
    return std::min(kMaxRadius,
                    std::sqrt(2.0 * level * var) * (1 + 1e-3) + 0.05);
  };
  const double hx = half(p.cov2d[0]), hy = half(p.cov2d[2]);
  const double y_lo = std::ceil(p.mean2d[1] - hy - 0.5);
  const double y_hi = std::floor(p.mean2d[1] + hy - 0.5);
  const double x_lo = std::ceil(p.mean2d[0] - hx - 0.5);
  const double x_hi = std::floor(p.mean2d[0] + hx - 0.5);
  if (y_hi < y_lo || x_hi < x_lo) return false;
  auto clamp_int = [](double v) {
    return static_cast<int>(std::clamp(v, -1.0e8, 1.0e8));
  };
  s->row_min = clamp_int(y_lo);
  s->row_max = clamp_int(y_hi);
  // Row intervals of the ellipse a dx^2 + 2 b dx dy + c dy^2 <= 2 level:
  // centre -b/a dy, half-width^2 = 2 level / a - dy^2 / (a cov_yy).
  const double a = p.conic[0], b = p.conic[1];
  const double shear = -b / a, reach = 2.0 * level / a;
  const double narrowing = 1.0 / (a * p.cov2d[2]);
  const bool usable = std::isfinite(shear) && std::isfinite(reach) &&
                      std::isfinite(narrowing) && reach < 1e30;
  s->shear = usable ? static_cast<float>(shear) : 0.f;
  s->reach = usable ? static_cast<float>(reach) * 1.001f : 1e30f;
  s->narrowing = usable ? static_cast<float>(narrowing) * 0.999f : 0.f;
  auto tile = [](int v) {
    return v >= 0 ? v / kTileSize : -((-v + kTileSize - 1) / kTileSize);
  };
  tiles->x0 = tile(clamp_int(x_lo));
  tiles->x1 = tile(clamp_int(x_hi)) + 1;
  tiles->y0 = tile(s->row_min);
  tiles->y1 = tile(s->row_max) + 1;
  return true;
}

// Splat fields (colour excluded) of a projected Gaussian.
Splat MakeSplat(const ProjectedGaussian& p, float opacity) {
  Splat s{};
  s.mean_x = static_cast<float>(p.mean2d[0]);
  s.mean_y = static_cast<float>(p.mean2d[1]);
  s.conic_a = static_cast<float>(p.conic[0]);
  s.conic_b = static_cast<float>(p.conic[1]);
  s.conic_c = static_cast<float>(p.conic[2]);
  s.opacity = opacity;
  return s;
}

// Clamped colour of Gaussian i into s->color; returns the clamped-bit mask.
// The base colour 0.5 + C0 DC is first stored as `conventions` say
// (StoredBaseColor).
uint8_t ShadeSplat(const GaussianModel& model, size_t i, int degree,
                   const RenderConventions& conventions,
                   const ProjectionCamera& cam, Splat* s) {
  const float* m = &model.means[3 * i];
  const double dir[3] = {m[0] - cam.center[0], m[1] - cam.center[1],
                         m[2] - cam.center[2]};
  double rgb[3];
  ShColorUnclamped(degree, &model.sh_dc[3 * i],
                   model.sh_rest.data() + i * model.sh_rest_stride(), dir, rgb);
  if (conventions.clamp_base_color || conventions.base_opacity_8bit) {
    for (int ch = 0; ch < 3; ++ch) {
      const double base = kShC0 * model.sh_dc[3 * i + ch] + 0.5;
      rgb[ch] += StoredBaseColor(base, conventions) - base;
    }
  }
  if (conventions.compact_work_buffer) {
    for (int ch = 0; ch < 3; ++ch) rgb[ch] = CompactColor(rgb[ch], ch);
  }
  uint8_t clamped = 0;
  for (int ch = 0; ch < 3; ++ch) {
    if (!(rgb[ch] >= 0)) clamped |= uint8_t(1u << ch);
    s->color[ch] = clamped & (1u << ch) ? 0.f : static_cast<float>(rgb[ch]);
  }
  return clamped;
}

}  // namespace

size_t CpuRenderContext::Bytes() const {
  return sizeof(*this) + splat_ids.capacity() * sizeof(uint32_t) +
         color_clamped.capacity() + splats.capacity() * sizeof(Splat) +
         (bins.offsets.capacity() + bins.ids.capacity() +
          bins.splat_offsets.capacity() + bins.entries.capacity()) *
             sizeof(uint32_t) +
         blend.final_T.capacity() * sizeof(float) +
         blend.n_contrib.capacity() * sizeof(uint32_t) + visible.capacity();
}

PixelRect ResolveRenderRect(const RenderCamera& camera,
                            const RenderOptions& options) {
  if (camera.width <= 0 || camera.height <= 0) {
    Fail("render: camera has an empty image size " +
         std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  if (!(camera.fx > 0) || !(camera.fy > 0)) {
    Fail("render: camera focal lengths must be positive");
  }
  if (options.rect.empty()) return {0, 0, camera.width, camera.height};
  const PixelRect& r = options.rect;
  if (r.x0 < 0 || r.y0 < 0 || r.x0 + r.width > camera.width ||
      r.y0 + r.height > camera.height) {
    Fail("render: pixel rectangle " + std::to_string(r.x0) + "," +
         std::to_string(r.y0) + " " + std::to_string(r.width) + "x" +
         std::to_string(r.height) + " is not inside the " +
         std::to_string(camera.width) + "x" + std::to_string(camera.height) +
         " frame");
  }
  return r;
}

namespace {

// True when `conventions` drop the splat centred at `mean2d` (pixels).
bool CulledByCentre(const ProjectionCamera& cam, const double* mean2d,
                    const RenderConventions& conventions) {
  const double limit = conventions.cull_centre_outside;
  if (limit == 0) return false;
  const double u = 2.0 * mean2d[0] / cam.width - 1.0;
  const double v = 2.0 * mean2d[1] / cam.height - 1.0;
  return !(std::abs(u) <= limit && std::abs(v) <= limit);
}

// The 2D covariance (xx, xy, yy)'s eigenvalues as mid +- r: mid the mean of
// the diagonal, r^2 = ((xx - yy) / 2)^2 + xy^2 (no cancellation).
struct Eigenvalues2d {
  double mid, r2;
  explicit Eigenvalues2d(const double* cov)
      : mid(0.5 * (cov[0] + cov[2])),
        r2(0.25 * (cov[0] - cov[2]) * (cov[0] - cov[2]) + cov[1] * cov[1]) {}
};

// Caps the splat's screen extent 2 sqrt(2 lambda) along each axis of its
// ellipse at `cap` pixels: the eigenvalues of p->cov2d above cap^2 / 8 are
// lowered to it (the eigenvectors kept), and the conic follows. The tiles
// and radius stay those of the larger ellipse, a superset.
void CapExtent(double cap, ProjectedGaussian* p) {
  const double limit = cap * cap / 8;
  double* cov = p->cov2d;
  const Eigenvalues2d eigen(cov);
  const double r = std::sqrt(eigen.r2);
  const double l1 = eigen.mid + r, l2 = eigen.mid - r;
  if (!(l1 > limit)) return;
  const double c1 = limit, c2 = std::min(l2, limit);
  if (!(r > 0)) {
    cov[0] = cov[2] = c1, cov[1] = 0;
  } else {
    // cov' = c2 I + (c1 - c2) e1 e1^T, e1 e1^T = (cov - l2 I) / (l1 - l2).
    const double k = (c1 - c2) / (l1 - l2);
    cov[0] = c2 + k * (cov[0] - l2);
    cov[1] = k * cov[1];
    cov[2] = c2 + k * (cov[2] - l2);
  }
  InvertCovariance2d(cov, p->conic);
}

// Rebuilds p->cov2d from gaussian-splats-3d's eigen decomposition: the
// half gap between the eigenvalues at least sqrt(floor), the major axis
// along normalize(b, lambda1 - a). False when the minor eigenvalue is then
// not positive (the viewer draws nothing). The tiles stay Inria's, whose
// radius takes lambda1 with the same floor of 0.1.
bool FloorEigenGap(double floor, ProjectedGaussian* p) {
  double* cov = p->cov2d;
  const Eigenvalues2d eigen(cov);
  if (!std::isfinite(eigen.r2)) return false;
  const double gap = std::sqrt(std::max(floor, eigen.r2));
  const double l1 = eigen.mid + gap, l2 = eigen.mid - gap;
  if (!(l2 > 0)) return false;
  double ex = cov[1], ey = l1 - cov[0];
  const double norm = std::hypot(ex, ey);
  // A zero axis only when b = 0 and a - d = 2 gap: the x axis is the major.
  ex = norm > 0 ? ex / norm : 1.0;
  ey = norm > 0 ? ey / norm : 0.0;
  cov[0] = l2 + (l1 - l2) * ex * ex;
  cov[1] = (l1 - l2) * ex * ey;
  cov[2] = l2 + (l1 - l2) * ey * ey;
  return InvertCovariance2d(cov, p->conic) && std::isfinite(p->conic[0]) &&
         std::isfinite(p->conic[1]) && std::isfinite(p->conic[2]);
}

// True when the ellipse of p->cov2d spans fewer than `min_extent` pixels
// along its major axis, 2 sqrt(2 lambda1).
bool NarrowerThan(double min_extent, const ProjectedGaussian& p) {
  const Eigenvalues2d eigen(p.cov2d);
  const double lambda1 = eigen.mid + std::sqrt(eigen.r2);
  return !(2 * std::sqrt(2 * lambda1) >= min_extent);
}

// Replaces Inria's 0.3 px^2 dilation of p->cov2d by `dilation` (<= 0.3:
// the tiles and radius stay a superset); false if the covariance is then
// degenerate.
bool Redilate(double dilation, ProjectedGaussian* p) {
  p->cov2d[0] += dilation - kCovDilation;
  p->cov2d[2] += dilation - kCovDilation;
  return InvertCovariance2d(p->cov2d, p->conic) && std::isfinite(p->conic[0]) &&
         std::isfinite(p->conic[1]) && std::isfinite(p->conic[2]);
}

// A splat's scales, rotation and opacity through PlayCanvas' compact work
// buffer (CompactSplat) into the float arrays the projection reads.
void PackCompact(const float* log_scale, const float* quat,
                 float* packed_log_scale, float* packed_quat, double* opacity) {
  double s[3] = {log_scale[0], log_scale[1], log_scale[2]};
  double q[4] = {quat[0], quat[1], quat[2], quat[3]};
  CompactSplat(s, q, opacity);
  for (int k = 0; k < 3; ++k) packed_log_scale[k] = static_cast<float>(s[k]);
  for (int k = 0; k < 4; ++k) packed_quat[k] = static_cast<float>(q[k]);
}

// Per-Gaussian results of the projection stage, indexed by Gaussian id.
struct ProjectedModel {
  // Blending parameters; filled only where binned (no value-initialisation:
  // it would cost a 64-byte write per Gaussian).
  std::unique_ptr<Splat[]> splats;
  // Tiles to bin into (Inria's rectangle cut to the rendered tiles and to
  // where alpha can reach 1/255), camera depth, colour-clamp bits.
  std::vector<TileRange> tiles;
  std::vector<double> depth;
  std::vector<uint8_t> binned, clamped;
};

// Projects and shades every Gaussian that can touch `render_tiles`; sets
// ctx->visible. Parallel over Gaussians.
ProjectedModel ProjectModel(const GaussianModel& model,
                            const TileRange& render_tiles,
                            CpuRenderContext* ctx) {
  const size_t n = model.size();
  ProjectedModel out;
  out.splats.reset(new Splat[n]);
  out.tiles.resize(n), out.depth.resize(n);
  out.binned.assign(n, 0), out.clamped.assign(n, 0);
  ctx->visible.assign(n, 0);
  const ProjectionCamera& cam = ctx->camera;
  const RenderConventions& conventions = ctx->conventions;
  const double extent_cap =
      conventions.extent_cap_px > 0
          ? std::min({conventions.extent_cap_px, cam.width, cam.height})
          : 0;
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < n; ++i) {
    const float* mean = &model.means[3 * i];
    const float* log_scale = &model.log_scales[3 * i];
    const float* quat = &model.quats[4 * i];
    float packed_log_scale[3], packed_quat[4];
    double packed_opacity = 0;
    if (conventions.compact_work_buffer) {
      packed_opacity = Sigmoid(model.opacity_logits[i]);
      PackCompact(log_scale, quat, packed_log_scale, packed_quat,
                  &packed_opacity);
      log_scale = packed_log_scale;
      quat = packed_quat;
    }
    if (!MayTouchTiles(cam, mean, log_scale, render_tiles)) continue;
    ProjectedGaussian p;
    if (!ProjectForward(cam, mean, log_scale, quat, &p)) continue;
    if (CulledByCentre(cam, p.mean2d, conventions)) continue;
    if (conventions.dilation_px2 >= 0 &&
        !Redilate(conventions.dilation_px2, &p)) {
      continue;
    }
    if (conventions.min_extent_px > 0 &&
        NarrowerThan(conventions.min_extent_px, p)) {
      continue;
    }
    if (extent_cap > 0) CapExtent(extent_cap, &p);
    if (conventions.eigen_gap_floor > 0 &&
        !FloorEigenGap(conventions.eigen_gap_floor, &p)) {
      continue;
    }
    if (Intersect(p.tiles, render_tiles).empty()) continue;
    ctx->visible[i] = 1;
    // The sigmoid only for splats that reach the frame (the hot path).
    const double opacity = conventions.compact_work_buffer
                               ? packed_opacity
                               : Sigmoid(model.opacity_logits[i]);
    const float stored_opacity =
        static_cast<float>(StoredOpacity(opacity, conventions));
    Splat& splat = out.splats[i];
    splat = MakeSplat(p, stored_opacity);
    TileRange support;
    if (!AlphaSupport(p, stored_opacity, &splat, &support)) continue;
    out.tiles[i] = Intersect(Intersect(p.tiles, render_tiles), support);
    if (out.tiles[i].empty()) continue;
    out.binned[i] = 1;
    out.depth[i] = p.depth;
    out.clamped[i] =
        ShadeSplat(model, i, ctx->active_sh_degree, conventions, cam, &splat);
  }
  return out;
}

// Orders the binned Gaussians front to back (ties by id) into ctx->splats,
// ctx->splat_ids and ctx->color_clamped; returns their tile ranges.
std::vector<TileRange> SortSplats(const ProjectedModel& projected,
                                  CpuRenderContext* ctx) {
  // Sort (depth, id) pairs held together: indirect comparisons through
  // depth[] miss the cache on large models.
  std::vector<std::pair<double, uint32_t>> order;
  for (size_t i = 0; i < projected.binned.size(); ++i) {
    if (projected.binned[i]) {
      order.emplace_back(projected.depth[i], static_cast<uint32_t>(i));
    }
  }
  std::sort(order.begin(), order.end());
  const size_t m = order.size();
  ctx->splat_ids.resize(m), ctx->splats.resize(m);
  ctx->color_clamped.resize(m);
  std::vector<TileRange> splat_tiles(m);
  for (size_t k = 0; k < m; ++k) {
    const uint32_t i = order[k].second;
    ctx->splat_ids[k] = i;
    ctx->splats[k] = projected.splats[i];
    ctx->color_clamped[k] = projected.clamped[i];
    splat_tiles[k] = projected.tiles[i];
  }
  return splat_tiles;
}

}  // namespace

void CpuRasterizer::Forward(const GaussianModel& model,
                            const RenderCamera& camera,
                            const RenderOptions& options, ImageRGB* image,
                            std::unique_ptr<RenderContext>* context) {
  const PixelRect rect = ResolveRenderRect(camera, options);
  auto ctx = std::make_unique<CpuRenderContext>();
  ctx->camera = MakeProjectionCamera(camera);
  ctx->frame_width = camera.width, ctx->frame_height = camera.height;
  CheckRenderConventions(options.conventions);
  ctx->conventions = options.conventions;
  if (options.conventions.unclamped_jacobian) {
    // No clamp: the limits it applies x/z and y/z at are infinite (the
    // backward pass reads the same camera, so its gradient stays exact).
    ctx->camera.tan_fovx = std::numeric_limits<double>::infinity();
    ctx->camera.tan_fovy = std::numeric_limits<double>::infinity();
  }
  ctx->active_sh_degree = EffectiveShDegree(
      options.active_sh_degree, model.sh_degree, options.conventions);
  ctx->background = options.background;
  ctx->num_gaussians = model.size();
  const TileRange render_tiles =
      TilesCoveringRect(rect.x0, rect.y0, rect.width, rect.height);
  const std::vector<TileRange> splat_tiles =
      SortSplats(ProjectModel(model, render_tiles, ctx.get()), ctx.get());
  BinSplats(splat_tiles, render_tiles, &ctx->bins);
  RasterizeForward(ctx->splats, ctx->bins, rect, options.background, image,
                   &ctx->blend,
                   BlendMode{options.conventions.falloff,
                             options.conventions.composite_8bit});
  if (context != nullptr) *context = std::move(ctx);
}

void CpuRasterizer::AccumulateBlendWeights(const GaussianModel& model,
                                           const RenderCamera& camera,
                                           const RenderOptions& options,
                                           std::vector<double>* weights) {
  if (weights->size() != model.size()) {
    Fail("render: blend weights need one entry per Gaussian");
  }
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  Forward(model, camera, options, &image, &context);
  const auto& ctx = static_cast<const CpuRenderContext&>(*context);
  std::vector<double> per_splat(ctx.splats.size(), 0.0);
  AccumulateSplatWeights(ctx.splats, ctx.bins, ctx.blend.rect, &per_splat,
                         ctx.conventions.falloff);
  for (size_t k = 0; k < per_splat.size(); ++k) {
    (*weights)[ctx.splat_ids[k]] += per_splat[k];
  }
}

namespace {

// Sizes every gradient array for `model` without clearing: the backward
// pass writes every entry (zeroing takes a serial pass over ~0.25 KB per
// Gaussian otherwise).
void SizeGradients(const GaussianModel& model, GaussianGradients* grads) {
  const size_t n = model.size();
  grads->means.resize(3 * n), grads->log_scales.resize(3 * n);
  grads->quats.resize(4 * n), grads->opacity_logits.resize(n);
  if (grads->compact_sh) {
    grads->sh_dc.clear(), grads->sh_rest.clear();
    grads->sh_color_grad.resize(3 * n), grads->sh_view_dir.resize(3 * n);
  } else {
    grads->sh_dc.resize(3 * n);
    grads->sh_rest.resize(n * static_cast<size_t>(model.sh_rest_stride()));
    grads->sh_color_grad.clear(), grads->sh_view_dir.clear();
  }
  grads->mean2d_grad_norm.resize(n), grads->mean2d_grad_norm_ndc.resize(n);
}

// Writes every gradient of Gaussian i: from its splat's blending gradient
// g (through SH, the sigmoid and the projection), or zeros if g is null.
void GaussianBackward(const GaussianModel& model, const CpuRenderContext& ctx,
                      size_t i, const SplatGrad* g, uint8_t color_clamped,
                      GaussianGradients* grads) {
  const int stride = model.sh_rest_stride();
  // Compact SH gradients: the coefficient products go to scratch and only
  // their factors (colour gradient, view direction) are kept.
  float scratch_dc[3], scratch_rest[45];
  const bool compact = grads->compact_sh;
  float* grad_dc = compact ? scratch_dc : &grads->sh_dc[3 * i];
  float* grad_rest =
      compact ? scratch_rest : grads->sh_rest.data() + i * stride;
  std::fill(grad_rest, grad_rest + stride, 0.f);
  std::fill_n(grad_dc, 3, 0.f);
  if (compact) {
    std::fill_n(&grads->sh_color_grad[3 * i], 3, 0.f);
    std::fill_n(&grads->sh_view_dir[3 * i], 3, 0.f);
  }
  double grad_mean[3] = {0, 0, 0}, grad_ls[3] = {0, 0, 0};
  double grad_q[4] = {0, 0, 0, 0}, grad_logit = 0;
  double grad_mean2d[2] = {0, 0};
  if (g != nullptr) {
    const ProjectionCamera& cam = ctx.camera;
    const float* mean = &model.means[3 * i];
    double grad_rgb[3];
    for (int ch = 0; ch < 3; ++ch) {
      grad_rgb[ch] = color_clamped & (1u << ch) ? 0.0 : g->color[ch];
    }
    const double dir[3] = {mean[0] - cam.center[0], mean[1] - cam.center[1],
                           mean[2] - cam.center[2]};
    ShColorBackward(ctx.active_sh_degree, &model.sh_dc[3 * i],
                    model.sh_rest.data() + i * stride, dir, grad_rgb, grad_dc,
                    grad_rest, grad_mean);
    if (compact) {
      for (int d = 0; d < 3; ++d) {
        grads->sh_color_grad[3 * i + d] = static_cast<float>(grad_rgb[d]);
        grads->sh_view_dir[3 * i + d] = static_cast<float>(dir[d]);
      }
    }
    const double s = Sigmoid(model.opacity_logits[i]);
    grad_logit = g->opacity * s * (1 - s);
    grad_mean2d[0] = g->mean_x, grad_mean2d[1] = g->mean_y;
    const double grad_conic[3] = {g->conic_a, g->conic_b, g->conic_c};
    ProjectBackward(cam, mean, &model.log_scales[3 * i], &model.quats[4 * i],
                    grad_mean2d, grad_conic, grad_mean, grad_ls, grad_q);
  }
  for (int d = 0; d < 3; ++d) {
    grads->means[3 * i + d] = static_cast<float>(grad_mean[d]);
    grads->log_scales[3 * i + d] = static_cast<float>(grad_ls[d]);
  }
  for (int d = 0; d < 4; ++d) {
    grads->quats[4 * i + d] = static_cast<float>(grad_q[d]);
  }
  grads->opacity_logits[i] = static_cast<float>(grad_logit);
  // sqrt rather than hypot: no overflow risk in double, much cheaper.
  const double gx = grad_mean2d[0], gy = grad_mean2d[1];
  const double half_w = 0.5 * ctx.frame_width, half_h = 0.5 * ctx.frame_height;
  grads->mean2d_grad_norm[i] = static_cast<float>(std::sqrt(gx * gx + gy * gy));
  grads->mean2d_grad_norm_ndc[i] = static_cast<float>(
      std::sqrt(gx * gx * half_w * half_w + gy * gy * half_h * half_h));
}

}  // namespace

void CpuRasterizer::Backward(const GaussianModel& model,
                             const RenderContext& context,
                             const ImageRGB& grad_image,
                             GaussianGradients* grads) {
  const auto& ctx = dynamic_cast<const CpuRenderContext&>(context);
  const PixelRect& rect = ctx.blend.rect;
  if (grad_image.width != rect.width || grad_image.height != rect.height ||
      model.size() != ctx.num_gaussians) {
    Fail(
        "render backward: gradient image or model does not match the "
        "forward pass");
  }
  if (ctx.conventions.ForwardOnly()) {
    Fail(
        "render backward: the base-colour clamp, 8-bit storage, extent cap, "
        "dilation, eigenvalue floor, minimum extent, falloff, 8-bit "
        "composite and compact packing of render conventions have no "
        "backward pass (forward only)");
  }
  std::vector<SplatGrad> splat_grads;
  RasterizeBackward(ctx.splats, ctx.bins, ctx.background, ctx.blend, grad_image,
                    &splat_grads);
  SizeGradients(model, grads);
  grads->visible = ctx.visible;
  grads->sh_active_degree = ctx.active_sh_degree;
  // Visit Gaussians in id order (not depth order) so the model and gradient
  // arrays, ~0.5 KB per Gaussian at SH degree 3, stream through the cache.
  std::vector<int32_t> splat_of(model.size(), -1);
  for (size_t k = 0; k < ctx.splat_ids.size(); ++k) {
    splat_of[ctx.splat_ids[k]] = static_cast<int32_t>(k);
  }
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < model.size(); ++i) {
    const int32_t k = splat_of[i];
    GaussianBackward(model, ctx, i, k < 0 ? nullptr : &splat_grads[k],
                     k < 0 ? 0 : ctx.color_clamped[k], grads);
  }
}

std::unique_ptr<Rasterizer> MakeCpuRasterizer() {
  return std::make_unique<CpuRasterizer>();
}

}  // namespace watergs
