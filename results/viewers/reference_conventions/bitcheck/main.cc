// Renders a model with HEAD's CPU rasterizer and with the working tree's
// (default conventions) at every camera of a workspace (and random scenes), and
// compares the floats bit for bit.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "gaussian/formats/model_io.h"
#include "gaussian/rasterizer.h"
#include "tests/gaussian/rasterizer_test_scenes.h"
extern "C" void OldRender(int n, int sh_degree, const float* means,
                          const float* log_scales, const float* quats,
                          const float* opacity, const float* dc,
                          const float* rest, const double* cam, int active_sh,
                          float* out);
using namespace watergs;
static bool Same(const GaussianModel& m, const RenderCamera& c, int active_sh,
                 const char* what) {
  double cam[20];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) cam[r * 3 + k] = c.R(r, k);
  for (int r = 0; r < 3; ++r) cam[9 + r] = c.t[r];
  cam[12] = c.fx, cam[13] = c.fy, cam[14] = c.cx, cam[15] = c.cy;
  cam[16] = c.width, cam[17] = c.height, cam[18] = c.near_plane,
  cam[19] = c.far_plane;
  std::vector<float> old(size_t(3) * c.width * c.height);
  OldRender(int(m.size()), m.sh_degree, m.means.data(), m.log_scales.data(),
            m.quats.data(), m.opacity_logits.data(), m.sh_dc.data(),
            m.sh_rest.data(), cam, active_sh, old.data());
  RenderOptions o;
  o.active_sh_degree = active_sh;
  ImageRGB img;
  MakeCpuRasterizer()->Forward(m, c, o, &img, nullptr);
  const bool same =
      std::memcmp(old.data(), img.data.data(), sizeof(float) * old.size()) == 0;
  double sum = 0;
  for (float v : img.data) sum += v;
  std::printf("%s: %s (%zu values, sum %.6f)\n", what,
              same ? "bit-identical" : "DIFFERENT", old.size(), sum);
  return same;
}
int main(int argc, char** argv) {
  bool all = true;
  for (unsigned seed = 0; seed < 20; ++seed) {
    const RenderCamera cam = testing::RandomCamera(70 + seed, 50 + seed, seed);
    testing::SceneSpec spec;
    spec.count = 200;
    spec.sh_degree = seed % 4;
    spec.margin = 40;
    char what[64];
    std::snprintf(what, sizeof what, "random scene %u", seed);
    all &= Same(testing::RandomScene(cam, spec, 1000 + seed), cam,
                seed % 2 ? -1 : 0, what);
  }
  if (argc > 1) {
    const ModelData d = ReadModelFile(argv[1]);
    // The cameras of a cameras.json (Inria's: rotation = camera-to-world rows,
    // position = centre; plus fx, fy, cx, cy, width, height).
    std::ifstream in(argv[2]);
    const nlohmann::json cams = nlohmann::json::parse(in);
    for (const auto& j : cams) {
      RenderCamera c;
      c.width = j["width"], c.height = j["height"];
      c.fx = j["fx"], c.fy = j["fy"], c.cx = j["cx"], c.cy = j["cy"];
      Eigen::Matrix3d rot;
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) rot(r, k) = j["rotation"][r][k];
      const Eigen::Vector3d pos(j["position"][0], j["position"][1],
                                j["position"][2]);
      c.R = rot.transpose();
      c.t = -c.R * pos;
      const std::string what =
          std::string(argv[1]) + " " + std::string(j["img_name"]);
      for (int sh : {-1, 0}) all &= Same(d.model, c, sh, what.c_str());
    }
  }
  std::printf("%s\n", all ? "ALL BIT-IDENTICAL" : "SOME DIFFER");
  return all ? 0 : 1;
}
