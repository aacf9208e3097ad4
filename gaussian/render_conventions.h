// Render conventions: the per-splat choices in which 3DGS renderers differ
// from Inria's (and watergs') while reading the same file, applied by the
// rasterizer when asked (RenderOptions::conventions). Web viewers cull
// splats by their centre, evaluate fewer SH bands, store colours, opacities
// and shapes in few bits, rebuild small splats' ellipses from floored
// eigenvalues, cap the screen extent of large splats, cut the falloff at
// 2.83 sigma and composite back to front into an 8-bit canvas; watergs
// renders as Inria does. The owner's reading of a screenshot (`detect`)
// renders its reference the way the viewer did (results/viewers/ measures
// the gap: on fern, whose splats are mostly a pixel wide,
// gaussian-splats-3d's screenshots sit 26.4 dB from watergs' render and
// 50.4 dB from the `web` set's, PlayCanvas' 21.3 and 47.2 dB from
// `playcanvas`'). Each named set lives in one registry here, the only list
// of their names.
#pragma once

#include <string>
#include <vector>

namespace watergs {

// How a splat's alpha falls off with the Mahalanobis distance d from its
// centre (o its opacity; every mode skips alpha below 1/255 and caps it at
// 0.99 as Inria does).
enum class Falloff {
  kInria,       // o exp(-d^2 / 2) (Inria, watergs)
  kCutAt8,      // the same, 0 beyond d^2 = 8 (2.83 sigma, where
                // gaussian-splats-3d's quad ends)
  kNormalized,  // o (exp(-d^2 / 2) - e^-4) / (1 - e^-4), 0 beyond d^2 = 8
                // (PlayCanvas: 0 at its quad's edge)
};

struct RenderConventions {
  // Splats whose projected centre lies outside this multiple of the frame
  // (|2 x / width - 1| or |2 y / height - 1| above it, x, y the centre in
  // pixels) are dropped, however far their footprint reaches into the frame
  // (gaussian-splats-3d: 1.2). 0: none dropped by their centre (Inria keeps
  // every splat in front of the near plane whose 3-sigma square touches the
  // image).
  double cull_centre_outside = 0;
  // At most this SH degree is evaluated (gaussian-splats-3d's default: 0);
  // -1: the model's (or RenderOptions::active_sh_degree).
  int max_sh_degree = -1;
  // The base colour (0.5 + C0 * DC) is clamped to [0, 1] before the higher
  // bands are added (gaussian-splats-3d stores it in 8 bits: see
  // base_opacity_8bit); Inria clamps the final colour at 0 only, which
  // watergs always does.
  bool clamp_base_color = false;
  // The base colour and the opacity (after the sigmoid) are stored in 8
  // bits as floor(255 v) clamped to [0, 255] (gaussian-splats-3d's splat
  // buffer: both lose up to 1/255, half a level darker on average); implies
  // the base colour's clamp.
  bool base_opacity_8bit = false;
  // The splat's screen extent 2 sqrt(2 lambda) along each axis of its
  // ellipse (lambda an eigenvalue of the dilated 2D covariance; 2.83 sigma,
  // where PlayCanvas' quad ends) is capped at min(this, the frame's shorter
  // side) pixels, which shrinks the Gaussian along that axis (PlayCanvas:
  // 1024). 0: no cap.
  int extent_cap_px = 0;
  // The low-pass dilation added to the 2D covariance's diagonal, in px^2,
  // in [0, 0.3]; -1: Inria's 0.3. (PlayCanvas adds 0.3 to a covariance in
  // half-pixel units: 0.075 px^2.)
  double dilation_px2 = -1;
  // The perspective Jacobian is taken at the centre's own x/z and y/z,
  // without Inria's clamp to 1.3 tan(half-FOV) (PlayCanvas).
  bool unclamped_jacobian = false;
  // The ellipse drawn is rebuilt from the dilated 2D covariance (a, b; b, d)
  // as gaussian-splats-3d does: eigenvalues mid +- sqrt(max(this, disc)),
  // disc = ((a - d) / 2)^2 + b^2 in px^4, the larger's axis along
  // normalize(b, lambda1 - a). Near-round splats (disc below this) are drawn
  // stretched along that axis (vertical when b = 0), and dropped when the
  // smaller eigenvalue falls to 0 or below: the viewer's eigenvalue floor,
  // which Inria applies to the tile radius only. A floor on the squared
  // half gap disc, px^4 (gaussian-splats-3d: 0.1; at most 0.1 so Inria's
  // tiles still cover the ellipse). 0: none.
  double eigen_gap_floor = 0;
  // Splats whose ellipse is narrower than this many pixels along its major
  // axis, 2 sqrt(2 lambda1) with lambda1 the larger eigenvalue of the
  // dilated 2D covariance (the quad PlayCanvas draws, out to 2.83 sigma),
  // are dropped (PlayCanvas' minPixelSize, 2 in its half-pixel units: 1).
  // 0: none.
  double min_extent_px = 0;
  Falloff falloff = Falloff::kInria;
  // Each pixel is composited back to front into 8-bit channels, as a WebGL
  // viewer draws into its RGBA8 canvas: a splat's colour times alpha is
  // clamped to [0, 1] (PlayCanvas' premultiplied ONE, ONE_MINUS_SRC_ALPHA;
  // gaussian-splats-3d's SRC_ALPHA blend clamps the colour instead, the
  // same while colours stay within [0, 1]) and every blend clamped and
  // rounded to 1/255, so a bright splat behind others saturates at 1 before
  // they cover it (Inria sums in float front to back and clamps once). The
  // splats blended are Inria's: the same 1/255 skip, 0.99 cap and early
  // stop, which the viewers do not have (a fringe of a few levels).
  bool composite_8bit = false;
  // Each splat passes through PlayCanvas' compact work buffer before it is
  // drawn (CompactSplat): the scales on levels 1..255 of ln s over
  // [-12, 9] (steps of 21/255, 8.6%; level 0: no size), the rotation in
  // 11/11/10 bits, the opacity rounded to 1/255, the colour after the SH
  // clamped to [0, 4] in 11/11/10 bits. The scale levels move every
  // splat's extent by up to +-4.2%.
  bool compact_work_buffer = false;

  // True when the rasterizer renders exactly as without conventions.
  bool IsDefault() const;
  // True when a field without a backward pass is set (all but the centre
  // cull, the SH cap and the unclamped Jacobian).
  bool ForwardOnly() const;
};

// One named set of conventions: a renderer whose output the set imitates.
struct NamedRenderConventions {
  std::string name;
  RenderConventions conventions;
  std::string description;  // one line: whose conventions, which fields
};

// Every named set, watergs' own first. The names of `--render_conventions`
// and `--reference_conventions`.
const std::vector<NamedRenderConventions>& RenderConventionsRegistry();

// The registry's names joined by `separator` ("watergs|web|playcanvas").
std::string RenderConventionNames(const std::string& separator = "|");

// "name: description; ..." over the registry, for option help.
std::string RenderConventionsHelp();

// The set named `name`; an unknown name fails in one line listing the names
// (`option` names the option in the message).
const NamedRenderConventions& FindRenderConventions(const std::string& name,
                                                    const std::string& option);

// Fails in one line on values out of range: a centre cull neither 0 nor a
// finite positive multiple, a negative extent cap, a dilation outside
// [0, 0.3] other than -1, an eigenvalue floor outside [0, 0.1], a minimum
// extent negative or not finite.
void CheckRenderConventions(const RenderConventions& conventions);

// Fails in one line when `conventions` are not the default: for renderers
// that implement none of them (`who` names it, e.g. "the CUDA rasterizer").
void RequireDefaultConventions(const RenderConventions& conventions,
                               const std::string& who);

// The base colour 0.5 + C0 DC as the renderer stores it: clamped to [0, 1]
// (clamp_base_color) and floored to 1/255 (base_opacity_8bit), else as is.
double StoredBaseColor(double base, const RenderConventions& conventions);

// The opacity (after the sigmoid) as the renderer stores it: floored to
// 1/255 (base_opacity_8bit), else as is.
double StoredOpacity(double opacity, const RenderConventions& conventions);

// One splat's scales, rotation and opacity after PlayCanvas' compact work
// buffer (compact_work_buffer): log_scale[3] in natural log (a scale under
// 1e-10 becomes e^-30), quat[4] (w, x, y, z), unnormalised in, unit out
// with w >= 0 up to the packing's steps (a quaternion of norm <= 1e-12 is
// left as it is); opacity after the sigmoid.
void CompactSplat(double* log_scale, double* quat, double* opacity);

// A colour channel (0 red .. 2 blue) after the SH through the compact work
// buffer: clamped to [0, 4], 2047 steps for red and green, 1023 for blue.
double CompactColor(double value, int channel);

// The SH degree rendered: `active_sh_degree` (-1: the model's) capped by
// the model's degree and the conventions' max_sh_degree.
int EffectiveShDegree(int active_sh_degree, int model_sh_degree,
                      const RenderConventions& conventions);

}  // namespace watergs
