// Cost of one WATER-GS embedding iteration on a real scene, split into
// distortion, render, image loss, decoder, backward, density control and
// Adam; compares no layers with Identity only (must cost the same), all four
// layers, and random-crop rendering with whole frames. Medians over
// iterations.
//   embed_benchmark PLY WORKSPACE DECODER [ITERATIONS=15] [DOWNSCALE=1]
//                   [DEVICE=cpu|cuda]
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/ply_io.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/embedder.h"

namespace {

using namespace watergs;

struct Config {
  const char* name;
  const char* distortions;
  int crop_size;
  bool full_frame_loss;
  bool densify;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr,
                 "usage: embed_benchmark PLY WORKSPACE DECODER [ITERATIONS] "
                 "[DOWNSCALE] [DEVICE]\n");
    return 2;
  }
  const int iterations = argc > 4 ? std::stoi(argv[4]) : 15;
  WorkspaceOptions wo;
  wo.workspace_path = argv[2];
  wo.downscale = argc > 5 ? std::stoi(argv[5]) : 1;
  try {
    const Device device = ResolveDevice(argc > 6 ? argv[6] : "cpu");
    const PlyData ply = ReadPly(argv[1]);
    Decoder decoder = Decoder::Load(argv[3]);
    const Bits message = ParseMessage("text:WGS-26", decoder.NumBits());
    const Workspace workspace = Workspace::Open(wo);
    const WorkspaceViews views(workspace);
    const std::vector<size_t> train = workspace.TrainViews(false);
    const Config configs[] = {
        {"no layers, crop 128", "none", 128, false, false},
        {"identity only, crop 128", "identity", 128, false, false},
        {"4 layers, crop 128", "identity,gn:0.01,dropout:0.1,crop:0.1", 128,
         false, false},
        {"4 layers, crop 128, ADC", "identity,gn:0.01,dropout:0.1,crop:0.1",
         128, false, true},
        {"no layers, full frame, decoder crop", "none", 128, true, false},
        {"no layers, full frame, decoder frame", "none", 0, false, false},
    };
    std::printf(
        "%zu Gaussians, %d views %dx%d, %d iterations per config, rasterizer "
        "on %s (medians, ms)\n",
        ply.model.size(), int(train.size()), views.Camera(0).width,
        views.Camera(0).height, iterations, DeviceName(device).c_str());
    std::printf("%-38s %8s %6s %7s %6s %8s %8s %7s %6s\n", "config", "total",
                "dist", "render", "loss", "decoder", "backward", "density",
                "adam");
    for (const Config& c : configs) {
      EmbedOptions o = DefaultEmbedOptions(1000);
      o.density.densify_from_iter = 1;
      o.density.densification_interval = 5;
      if (std::string(c.distortions) != "none") {
        o.distortions = ParseDistortionList(c.distortions);
      }
      o.crop_size = c.crop_size;
      o.full_frame_image_loss = c.full_frame_loss;
      o.densify = c.densify;
      o.seed = 1;
      Embedder embedder(o, views, train, ply.model, workspace.SceneExtent(),
                        &decoder, message, MakeRasterizer(device));
      embedder.Step();  // warm-up (buffers, image cache)
      std::vector<double> total, dist, render, loss, dec, back, dens, adam;
      for (int i = 0; i < iterations; ++i) {
        const EmbedTimings t = embedder.Step().timings;
        total.push_back(1e3 * t.Total());
        dist.push_back(1e3 * t.distortion);
        render.push_back(1e3 * t.render);
        loss.push_back(1e3 * t.image_loss);
        dec.push_back(1e3 * t.decoder);
        back.push_back(1e3 * t.backward);
        dens.push_back(1e3 * t.density);
        adam.push_back(1e3 * t.adam);
      }
      std::printf("%-38s %8.1f %6.1f %7.1f %6.1f %8.1f %8.1f %7.1f %6.1f\n",
                  c.name, Median(total), Median(dist), Median(render),
                  Median(loss), Median(dec), Median(back), Median(dens),
                  Median(adam));
      std::fflush(stdout);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
