// The registry of named render conventions and their checks.
#include "gaussian/render_conventions.h"

#include <algorithm>
#include <cmath>

#include "gaussian/projection.h"
#include "gaussian/util/error.h"

namespace watergs {

bool RenderConventions::IsDefault() const {
  return cull_centre_outside == 0 && max_sh_degree < 0 && !clamp_base_color &&
         extent_cap_px == 0 && dilation_px2 == -1 && !unclamped_jacobian &&
         eigen_gap_floor == 0 && min_extent_px == 0 &&
         falloff == Falloff::kInria;
}

bool RenderConventions::ForwardOnly() const {
  return clamp_base_color || extent_cap_px > 0 || dilation_px2 >= 0 ||
         eigen_gap_floor > 0 || min_extent_px > 0 || falloff != Falloff::kInria;
}

const std::vector<NamedRenderConventions>& RenderConventionsRegistry() {
  static const std::vector<NamedRenderConventions> registry = [] {
    RenderConventions web;
    web.cull_centre_outside = 1.2;
    web.max_sh_degree = 0;
    web.clamp_base_color = true;
    web.eigen_gap_floor = 0.1;
    web.falloff = Falloff::kCutAt8;
    RenderConventions playcanvas;
    playcanvas.extent_cap_px = 1024;
    playcanvas.dilation_px2 = 0.075;
    playcanvas.unclamped_jacobian = true;
    playcanvas.min_extent_px = 1;
    playcanvas.falloff = Falloff::kNormalized;
    return std::vector<NamedRenderConventions>{
        {"watergs", RenderConventions(),
         "watergs' and Inria's: every splat whose footprint touches the "
         "frame, the model's SH, colour clamped at 0"},
        {"web", web,
         "gaussian-splats-3d's defaults: splats centred outside 1.2x the "
         "frame dropped, SH degree 0, base colour clamped to [0, 1], "
         "near-round splats' eigenvalues split by at least 2 sqrt(0.1) px^2, "
         "each splat cut at 2.83 sigma"},
        {"playcanvas", playcanvas,
         "PlayCanvas': screen extent capped at min(1024, the frame's "
         "shorter side) pixels, dilation 0.075 px^2, no Jacobian clamp, "
         "splats under 1 px across dropped, alpha falling to 0 at 2.83 "
         "sigma"},
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
         "asked: a centre cull, SH cap, colour clamp, extent cap, dilation, "
         "unclamped Jacobian, eigenvalue floor, minimum extent or falloff): "
         "use the CPU");
  }
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
