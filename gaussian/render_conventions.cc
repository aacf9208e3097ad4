// The registry of named render conventions and their checks.
#include "gaussian/render_conventions.h"

#include <algorithm>
#include <cmath>

#include "gaussian/projection.h"
#include "gaussian/util/error.h"

namespace watergs {

bool RenderConventions::IsDefault() const {
  return cull_centre_outside == 0 && max_sh_degree < 0 && !clamp_base_color &&
         !base_opacity_8bit && extent_cap_px == 0 && dilation_px2 == -1 &&
         !unclamped_jacobian && eigen_gap_floor == 0 && min_extent_px == 0 &&
         falloff == Falloff::kInria && !composite_8bit && !compact_work_buffer;
}

bool RenderConventions::ForwardOnly() const {
  return clamp_base_color || base_opacity_8bit || extent_cap_px > 0 ||
         dilation_px2 >= 0 || eigen_gap_floor > 0 || min_extent_px > 0 ||
         falloff != Falloff::kInria || composite_8bit || compact_work_buffer;
}

const std::vector<NamedRenderConventions>& RenderConventionsRegistry() {
  static const std::vector<NamedRenderConventions> registry = [] {
    RenderConventions web;
    web.cull_centre_outside = 1.2;
    web.max_sh_degree = 0;
    web.clamp_base_color = true;
    web.base_opacity_8bit = true;
    web.eigen_gap_floor = 0.1;
    web.falloff = Falloff::kCutAt8;
    web.composite_8bit = true;
    RenderConventions playcanvas;
    playcanvas.extent_cap_px = 1024;
    playcanvas.dilation_px2 = 0.075;
    playcanvas.unclamped_jacobian = true;
    playcanvas.min_extent_px = 1;
    playcanvas.falloff = Falloff::kNormalized;
    playcanvas.composite_8bit = true;
    playcanvas.compact_work_buffer = true;
    return std::vector<NamedRenderConventions>{
        {"watergs", RenderConventions(),
         "watergs' and Inria's: every splat whose footprint touches the "
         "frame, the model's SH, colour clamped at 0"},
        {"web", web,
         "gaussian-splats-3d's defaults: splats centred outside 1.2x the "
         "frame dropped, SH degree 0, base colour and opacity floored to 8 "
         "bits, near-round splats' eigenvalues split by at least 2 sqrt(0.1) "
         "px^2, each splat cut at 2.83 sigma, composited back to front in 8 "
         "bits"},
        {"playcanvas", playcanvas,
         "PlayCanvas': screen extent capped at min(1024, the frame's "
         "shorter side) pixels, dilation 0.075 px^2, no Jacobian clamp, "
         "splats under 1 px across dropped, alpha falling to 0 at 2.83 "
         "sigma, scales, rotation, opacity and colour packed in its compact "
         "work buffer, composited back to front in 8 bits"},
    };
  }();
  return registry;
}

std::string RenderConventionNames(const std::string& separator) {
  std::string names;
  for (const NamedRenderConventions& entry : RenderConventionsRegistry()) {
    if (!names.empty()) names += separator;
    names += entry.name;
  }
  return names;
}

std::string RenderConventionsHelp() {
  std::string help;
  for (const NamedRenderConventions& entry : RenderConventionsRegistry()) {
    if (!help.empty()) help += "; ";
    help += entry.name + ": " + entry.description;
  }
  return help;
}

const NamedRenderConventions& FindRenderConventions(const std::string& name,
                                                    const std::string& option) {
  for (const NamedRenderConventions& entry : RenderConventionsRegistry()) {
    if (entry.name == name) return entry;
  }
  Fail(option + ": unknown render conventions '" + Printable(name) +
       "' (one of " + RenderConventionNames(", ") + ")");
}

void CheckRenderConventions(const RenderConventions& conventions) {
  const double cull = conventions.cull_centre_outside;
  if (!(cull == 0 || (cull > 0 && std::isfinite(cull)))) {
    Fail(
        "render: the centre cull must be 0 (none) or a positive multiple "
        "of the frame");
  }
  if (conventions.extent_cap_px < 0) {
    Fail("render: the extent cap must be 0 (none) or positive pixels");
  }
  const double dilation = conventions.dilation_px2;
  if (!(dilation == -1 || (dilation >= 0 && dilation <= kCovDilation))) {
    Fail("render: the dilation must be -1 (Inria's 0.3) or in [0, 0.3] px^2");
  }
  const double floor = conventions.eigen_gap_floor;
  if (!(floor >= 0 && floor <= 0.1)) {
    Fail("render: the eigenvalue gap floor must be in [0, 0.1] px^4");
  }
  const double min_extent = conventions.min_extent_px;
  if (!(min_extent >= 0 && std::isfinite(min_extent))) {
    Fail("render: the minimum extent must be 0 (none) or positive pixels");
  }
}

void RequireDefaultConventions(const RenderConventions& conventions,
                               const std::string& who) {
  if (!conventions.IsDefault()) {
    Fail("render: " + who +
         " renders with watergs' conventions only (another renderer's were "
         "asked: a centre cull, SH cap, colour clamp, 8-bit storage, extent "
         "cap, dilation, unclamped Jacobian, eigenvalue floor, minimum "
         "extent, falloff, 8-bit composite or compact packing): use the CPU");
  }
}

double StoredBaseColor(double base, const RenderConventions& conventions) {
  if (conventions.base_opacity_8bit) {
    return std::clamp(std::floor(base * 255), 0.0, 255.0) / 255;
  }
  return conventions.clamp_base_color ? std::clamp(base, 0.0, 1.0) : base;
}

double StoredOpacity(double opacity, const RenderConventions& conventions) {
  if (!conventions.base_opacity_8bit) return opacity;
  return std::clamp(std::floor(opacity * 255), 0.0, 255.0) / 255;
}

namespace {

// v in [lo, hi] on `steps` + 1 levels: the level PlayCanvas' shader writes
// (uint(x + 0.5), clamped) and the value it reads back.
double PackUnorm(double v, double lo, double hi, double steps) {
  const double level =
      std::clamp(std::floor((v - lo) / (hi - lo) * steps + 0.5), 0.0, steps);
  return lo + level / steps * (hi - lo);
}

}  // namespace

void CompactSplat(double* log_scale, double* quat, double* opacity) {
  // Scales: levels 1..255 of ln(s) over [-12, 9], level 0 kept for
  // s < 1e-10 (no size).
  constexpr double kLogMin = -12, kLogMax = 9;
  for (int k = 0; k < 3; ++k) {
    log_scale[k] =
        log_scale[k] >= std::log(1e-10)
            ? std::max(PackUnorm(log_scale[k], kLogMin, kLogMax, 255),
                       kLogMin + (kLogMax - kLogMin) / 255)
            : -30;
  }
  // Rotation: p = (x, y, z) / sqrt(1 + w) of the unit quaternion with
  // w >= 0, each in [-1, 1] on 2047, 2047, 1023 steps; read back as
  // (1 - |p|^2, sqrt(2 - |p|^2) p).
  const double norm = std::sqrt(quat[0] * quat[0] + quat[1] * quat[1] +
                                quat[2] * quat[2] + quat[3] * quat[3]);
  if (norm > 1e-12) {
    const double sign = quat[0] < 0 ? -1.0 : 1.0;
    const double w = sign * quat[0] / norm;
    const double steps[3] = {2047, 2047, 1023};
    double p[3], d = 0;
    for (int k = 0; k < 3; ++k) {
      p[k] = PackUnorm(sign * quat[k + 1] / norm / std::sqrt(1 + w), -1, 1,
                       steps[k]);
      d += p[k] * p[k];
    }
    quat[0] = 1 - d;
    for (int k = 0; k < 3; ++k) {
      quat[k + 1] = std::sqrt(std::max(0.0, 2 - d)) * p[k];
    }
  }
  *opacity = PackUnorm(*opacity, 0, 1, 255);
}

double CompactColor(double value, int channel) {
  return PackUnorm(value, 0, 4, channel == 2 ? 1023 : 2047);
}

int EffectiveShDegree(int active_sh_degree, int model_sh_degree,
                      const RenderConventions& conventions) {
  int degree = active_sh_degree < 0
                   ? model_sh_degree
                   : std::min(active_sh_degree, model_sh_degree);
  if (conventions.max_sh_degree >= 0) {
    degree = std::min(degree, conventions.max_sh_degree);
  }
  return degree;
}

}  // namespace watergs
