// Rasterizer benchmark: forward, backward and forward+backward medians,
// splat-pixel throughput, render-context memory per Gaussian, and the cost
// of a crop relative to the full frame, on synthetic SfM-like scenes.
// Usage: raster_benchmark [--threads 2] [--repeats 15] [--sh_degree 3]
//        [--scenes 0|8|100|1000]  (all but 1000, the 8k scene, the 100k
//        scenes, a 1M-Gaussian scene at 1920x1080) [--device cpu|cuda]
// On CUDA, times include the host<->device copies of the interface and the
// device memory the rasterizer holds is reported per Gaussian.
#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "benchmarks/resident_raster.h"
#include "benchmarks/synthetic_scene.h"
#include "gaussian/backend.h"
#include "gaussian/cpu_rasterizer.h"
#include "gaussian/device.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"

namespace watergs {
namespace {

// Command-line settings.
struct BenchOptions {
  int threads = 2;
  int repeats = 15;
  int sh_degree = 3;
  // Which scenes: 0 = all but the 1M one, 8 = the 8k scene only, 100 = the
  // 100k ones only, 1000 = 1M Gaussians at 1920x1080.
  int scenes = 0;
  // Rasterizer under test.
  Device device = Device::kCpu;
  // With --scenes 1000: write the 1M scene (Inria PLY) and its camera
  // (JSON) into this folder, for another rasterizer to time the same work
  // (scripts/gsplat_timing.py).
  std::string write_scene;
};

// The camera as intrinsics and a row-major 4x4 world-to-camera matrix, with
// the provenance of the scene written beside it (which build and options).
void WriteCameraJson(const std::string& path, const RenderCamera& cam,
                     const nlohmann::json& provenance) {
  nlohmann::json j;
  j["width"] = cam.width, j["height"] = cam.height;
  j["fx"] = cam.fx, j["fy"] = cam.fy, j["cx"] = cam.cx, j["cy"] = cam.cy;
  std::vector<double> viewmat;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      viewmat.push_back(r == 3 ? (c == 3 ? 1.0 : 0.0)
                               : (c == 3 ? cam.t(r) : cam.R(r, c)));
    }
  }
  j["viewmat"] = viewmat;
  j["provenance"] = provenance;
  AtomicWriteFile(path, j.dump(1) + "\n");
}

double Seconds(std::chrono::steady_clock::time_point a) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - a)
      .count();
}

// Process CPU time in seconds (all threads): on a loaded shared machine,
// CPU time / threads estimates the uncontended wall time.
double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Splat-pixel pairs the blending loops work on: each tile's list length
// times the tile's pixels inside the rendered rectangle. A tile cut by the
// rectangle or the frame edge is only partly rendered, so counting all 256
// of its pixels overstated the figure: by 13% for the 128x128 crop at
// y0 = 116 (9 tile rows for 8 rows' worth of pixels) and by 1.2% for the
// 480x360 frame (its last tile row is half outside).
double SplatPixels(const CpuRenderContext& ctx) {
  const TileBins& bins = ctx.bins;
  const PixelRect& rect = ctx.blend.rect;
  const int tiles_x = bins.range.x1 - bins.range.x0;
  double pairs = 0;
  for (int ty = bins.range.y0; ty < bins.range.y1; ++ty) {
    const int rows = std::min((ty + 1) * kTileSize, rect.y0 + rect.height) -
                     std::max(ty * kTileSize, rect.y0);
    for (int tx = bins.range.x0; tx < bins.range.x1; ++tx) {
      const int cols = std::min((tx + 1) * kTileSize, rect.x0 + rect.width) -
                       std::max(tx * kTileSize, rect.x0);
      const size_t k =
          size_t(ty - bins.range.y0) * tiles_x + (tx - bins.range.x0);
      const size_t entries = bins.offsets[k + 1] - bins.offsets[k];
      if (rows > 0 && cols > 0) pairs += double(entries) * rows * cols;
    }
  }
  return pairs;
}

// Times forward, backward and both for one scene and rect; prints a line.
// Returns the forward+backward median in seconds.
double Run(const char* name, const GaussianModel& model,
           const RenderCamera& cam, const RenderOptions& options, int repeats,
           Device device) {
  if (device == Device::kCuda) ResetGpuMemoryPeak();
  auto rasterizer = MakeRasterizer(device);
  ImageRGB image;
  std::unique_ptr<RenderContext> context;
  rasterizer->Forward(model, cam, options, &image, &context);  // Warm-up.
  ImageRGB grad(image.width, image.height);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1e-5f, 1e-5f);
  for (float& g : grad.data) g = u(rng);
  GaussianGradients grads;
  rasterizer->Backward(model, *context, grad, &grads);
  std::vector<double> fwd, bwd, both, cpu;
  for (int r = 0; r < repeats; ++r) {
    const double c0 = CpuSeconds();
    auto t0 = std::chrono::steady_clock::now();
    rasterizer->Forward(model, cam, options, &image, &context);
    const double f = Seconds(t0);
    auto t1 = std::chrono::steady_clock::now();
    rasterizer->Backward(model, *context, grad, &grads);
    const double b = Seconds(t1);
    if (device == Device::kCuda) SampleGpuMemory();
    fwd.push_back(f), bwd.push_back(b), both.push_back(f + b);
    cpu.push_back(CpuSeconds() - c0);
  }
  const auto* ctx = dynamic_cast<const CpuRenderContext*>(context.get());
  if (!ctx) {
    const double device_bytes = double(GpuMemoryPeakBytes());
    std::printf(
        "%-26s N=%zu on %s\n"
        "    wall: forward %.2f ms, backward %.2f ms, fwd+bwd %.2f ms "
        "(%.0f/s); "
        "device memory %.0f B/Gaussian (peak over the runs)\n",
        name, model.size(), DeviceName(device).c_str(), 1e3 * Median(fwd),
        1e3 * Median(bwd), 1e3 * Median(both), 1.0 / Median(both),
        device_bytes / std::max<size_t>(1, model.size()));
    // The same passes with the model, image and gradients kept on the
    // device: the figure a device-resident trainer pays (docs/cuda.md).
    const bench::ResidentRasterTiming resident =
        bench::TimeResidentRaster(model, cam, options, repeats);
    if (resident.ok) {
      std::printf(
          "    device-resident: forward %.2f ms, backward %.2f ms, fwd+bwd "
          "%.2f ms (%.0f/s; CUDA events)\n",
          resident.forward_ms, resident.backward_ms, resident.both_ms,
          1e3 / resident.both_ms);
    }
    return Median(both);
  }
  const double pairs = SplatPixels(*ctx);
  size_t visible = 0;
  for (uint8_t v : ctx->visible) visible += v;
  const double min_cpu = *std::min_element(cpu.begin(), cpu.end());
  std::printf(
      "%-26s N=%zu visible=%zu splats=%zu tile-entries=%zu\n"
      "    wall: forward %.2f ms, backward %.2f ms, fwd+bwd %.2f ms (%.0f/s), "
      "%.0f M splat-pixel/s\n"
      "    cpu (all threads): fwd+bwd median %.2f ms, min %.2f ms; "
      "context %.0f B/Gaussian\n",
      name, model.size(), visible, ctx->splats.size(), ctx->bins.ids.size(),
      1e3 * Median(fwd), 1e3 * Median(bwd), 1e3 * Median(both),
      1.0 / Median(both), pairs / Median(both) * 1e-6, 1e3 * Median(cpu),
      1e3 * min_cpu, double(ctx->Bytes()) / std::max<size_t>(1, model.size()));
  return Median(both);
}

BenchOptions Parse(int argc, char** argv) {
  BenchOptions o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const int value = std::atoi(argv[i + 1]);
    if (flag == "--device")
      o.device = ResolveDevice(argv[i + 1]);
    else if (flag == "--threads")
      o.threads = value;
    else if (flag == "--repeats")
      o.repeats = value;
    else if (flag == "--sh_degree")
      o.sh_degree = value;
    else if (flag == "--scenes")
      o.scenes = value;
    else if (flag == "--write_scene")
      o.write_scene = argv[i + 1];
    else {
      std::fprintf(stderr, "raster_benchmark: unknown option %s\n", argv[i]);
      std::exit(2);
    }
  }
  return o;
}

}  // namespace
}  // namespace watergs

int main(int argc, char** argv) {
  using namespace watergs;
  BenchOptions opt;
  try {
    opt = Parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "raster_benchmark: %s\n", e.what());
    return 2;
  }
  omp_set_num_threads(opt.threads);
  std::printf(
      "threads=%d repeats=%d sh_degree=%d device=%s, medians unless noted; "
      "splat-pixels = tile-list entries x their tile's pixels inside the "
      "rendered rectangle\n",
      opt.threads, opt.repeats, opt.sh_degree, DeviceName(opt.device).c_str());
  RenderOptions full;
  if (opt.scenes == 1000) {
    const RenderCamera hd = BenchCamera(4);
    const GaussianModel huge =
        SyntheticScene(hd, 1000000, opt.sh_degree, true, 3);
    if (!opt.write_scene.empty()) {
      try {
        std::filesystem::create_directories(opt.write_scene);
        WritePly(opt.write_scene + "/scene_1m.ply", huge);
        WriteCameraJson(opt.write_scene + "/camera_1m.json", hd,
                        ProgramProvenance(argc, argv));
      } catch (const std::exception& e) {
        std::fprintf(stderr, "raster_benchmark: --write_scene %s: %s\n",
                     opt.write_scene.c_str(), e.what());
        return 2;
      }
      std::printf("wrote %s/scene_1m.ply and camera_1m.json\n",
                  opt.write_scene.c_str());
    }
    Run("trained-like 1M 1920x1080", huge, hd, full,
        std::max(3, opt.repeats / 3), opt.device);
    RenderOptions crop;
    crop.rect = {896, 476, 128, 128};
    Run("trained-like 1M crop128", huge, hd, crop, opt.repeats, opt.device);
    return 0;
  }
  const RenderCamera cam = BenchCamera();
  for (int active : {0, opt.sh_degree}) {
    if (opt.scenes == 100) break;
    full.active_sh_degree = active;
    const GaussianModel sfm =
        SyntheticScene(cam, 8000, opt.sh_degree, false, 1);
    const std::string name = "sfm-init 8k sh" + std::to_string(active);
    Run(name.c_str(), sfm, cam, full, opt.repeats, opt.device);
  }
  full.active_sh_degree = -1;
  if (opt.scenes == 8) return 0;
  const GaussianModel big = SyntheticScene(cam, 100000, opt.sh_degree, true, 2);
  const double full_time = Run("trained-like 100k", big, cam, full,
                               std::max(3, opt.repeats / 3), opt.device);
  RenderOptions crop;
  crop.rect = {176, 116, 128, 128};
  const double crop_time =
      Run("trained-like 100k crop128", big, cam, crop, opt.repeats, opt.device);
  std::printf("crop 128x128 / full 480x360: time ratio %.3f, area ratio %.3f\n",
              crop_time / full_time, 128.0 * 128.0 / (480.0 * 360.0));
  return 0;
}
