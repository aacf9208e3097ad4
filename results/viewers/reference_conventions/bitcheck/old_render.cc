// HEAD's CPU rasterizer (compiled with -Dwatergs=watergs_old) behind a C
// interface.
#include <cstring>

#include "gaussian/rasterizer.h"
extern "C" void OldRender(int n, int sh_degree, const float* means,
                          const float* log_scales, const float* quats,
                          const float* opacity, const float* dc,
                          const float* rest, const double* cam, int active_sh,
                          float* out) {
  using namespace watergs;
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  std::memcpy(m.means.data(), means, sizeof(float) * 3 * n);
  std::memcpy(m.log_scales.data(), log_scales, sizeof(float) * 3 * n);
  std::memcpy(m.quats.data(), quats, sizeof(float) * 4 * n);
  std::memcpy(m.opacity_logits.data(), opacity, sizeof(float) * n);
  std::memcpy(m.sh_dc.data(), dc, sizeof(float) * 3 * n);
  std::memcpy(m.sh_rest.data(), rest, sizeof(float) * m.sh_rest.size());
  RenderCamera c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) c.R(r, k) = cam[r * 3 + k];
  for (int r = 0; r < 3; ++r) c.t[r] = cam[9 + r];
  c.fx = cam[12], c.fy = cam[13], c.cx = cam[14], c.cy = cam[15];
  c.width = int(cam[16]), c.height = int(cam[17]);
  c.near_plane = cam[18], c.far_plane = cam[19];
  RenderOptions o;
  o.active_sh_degree = active_sh;
  ImageRGB img;
  MakeCpuRasterizer()->Forward(m, c, o, &img, nullptr);
  std::memcpy(out, img.data.data(), sizeof(float) * img.data.size());
}
