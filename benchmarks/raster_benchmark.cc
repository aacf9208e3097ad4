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
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "gaussian/cpu_rasterizer.h"
#include "gaussian/device.h"
#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_device.h"
#endif

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
};

// 480x360 (scale 1) or 1920x1080-like views of the same scene (scale 4).
RenderCamera BenchCamera(int scale = 1) {
  RenderCamera cam;
  cam.width = 480 * scale, cam.height = scale == 1 ? 360 : 270 * scale;
  cam.fx = cam.fy = 420 * scale;
  cam.cx = 0.5 * cam.width, cam.cy = 0.5 * cam.height;
  cam.R =
      Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.3, 1, 0).normalized()).matrix();
  cam.t = Eigen::Vector3d(0.1, -0.05, 0.2);
  return cam;
}

// Mean distance to the 3 nearest neighbours, via a uniform grid.
std::vector<double> ThreeNnDistance(const std::vector<Eigen::Vector3d>& pts,
                                    double cell) {
  auto key = [&](const Eigen::Vector3d& p, int dx, int dy, int dz) {
    const long long x = std::llround(std::floor(p.x() / cell)) + dx;
    const long long y = std::llround(std::floor(p.y() / cell)) + dy;
    const long long z = std::llround(std::floor(p.z() / cell)) + dz;
    return (x * 73856093LL) ^ (y * 19349663LL) ^ (z * 83492791LL);
  };
  std::unordered_multimap<long long, int> grid;
  for (size_t i = 0; i < pts.size(); ++i) grid.emplace(key(pts[i], 0, 0, 0), i);
  std::vector<double> out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    double best[3] = {1e30, 1e30, 1e30};
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          auto range = grid.equal_range(key(pts[i], dx, dy, dz));
          for (auto it = range.first; it != range.second; ++it) {
            if (it->second == static_cast<int>(i)) continue;
            const double d2 = (pts[it->second] - pts[i]).squaredNorm();
            if (d2 < best[2]) {
              best[2] = d2;
              std::sort(best, best + 3);
            }
          }
        }
      }
    }
    out[i] = std::sqrt((std::min(best[0], cell * cell) +
                        std::min(best[1], cell * cell) +
                        std::min(best[2], cell * cell)) /
                       3);
  }
  return out;
}

// Like an SfM initialisation: points on surfaces seen by the view and around
// it (a wavy backdrop at depth ~6 spanning 1.4 x the frustum, plus a few
// spherical objects at depth 2-4), isotropic scales from the 3-NN spacing
// (Inria's init), opacity 0.1; `trained` adds anisotropy and spread-out
// opacities.
GaussianModel SyntheticScene(const RenderCamera& cam, size_t n, int sh_degree,
                             bool trained, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Eigen::Vector3d> pts(n);
  const Eigen::Vector3d objects[4] = {
      {-0.8, 0.3, 3.0}, {0.6, -0.2, 2.5}, {0.1, 0.5, 4.0}, {1.2, 0.6, 3.5}};
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d p;
    if (i % 4 != 0) {
      const double sx = (u(rng) - 0.5) * 1.4 * cam.width / cam.fx;
      const double sy = (u(rng) - 0.5) * 1.4 * cam.height / cam.fy;
      const double z = 6 + 1.5 * std::sin(4 * sx) * std::cos(3 * sy);
      p = Eigen::Vector3d(sx * z, sy * z, z);
    } else {
      const Eigen::Vector3d dir(normal(rng), normal(rng), normal(rng));
      p = objects[i % 16 / 4] + 0.5 * dir.normalized();
    }
    pts[i] = cam.R.transpose() * (p - cam.t);
  }
  // Grid cells of ~2.5 x the expected spacing on the ~125 m^2 of surface.
  const double cell = 2.5 * std::sqrt(125.0 / n);
  const std::vector<double> spacing = ThreeNnDistance(pts, cell);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      m.means[3 * i + k] = static_cast<float>(pts[i][k]);
      const double aniso = trained ? std::exp(0.5 * normal(rng)) : 1.0;
      m.log_scales[3 * i + k] =
          static_cast<float>(std::log(spacing[i] * aniso));
      m.sh_dc[3 * i + k] = static_cast<float>(normal(rng));
    }
    for (int k = 0; k < 4; ++k) m.quats[4 * i + k] = float(normal(rng));
    m.opacity_logits[i] = trained ? float(normal(rng)) : -2.1972246f;
    for (int k = 0; k < m.sh_rest_stride(); ++k) {
      m.sh_rest[i * m.sh_rest_stride() + k] = float(0.1 * normal(rng));
    }
  }
  return m;
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

// Times forward, backward and both for one scene and rect; prints a line.
// Returns the forward+backward median in seconds.
double Run(const char* name, const GaussianModel& model,
           const RenderCamera& cam, const RenderOptions& options, int repeats,
           Device device) {
#ifdef WATERGS_WITH_CUDA
  if (device == Device::kCuda) ResetCudaMemoryPeak();
#endif
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
#ifdef WATERGS_WITH_CUDA
    if (device == Device::kCuda) SampleCudaMemory();
#endif
    fwd.push_back(f), bwd.push_back(b), both.push_back(f + b);
    cpu.push_back(CpuSeconds() - c0);
  }
  const auto* ctx = dynamic_cast<const CpuRenderContext*>(context.get());
  if (!ctx) {
    double device_bytes = 0;
#ifdef WATERGS_WITH_CUDA
    device_bytes = double(CudaMemoryPeakBytes());
#endif
    std::printf(
        "%-26s N=%zu on %s\n"
        "    wall: forward %.2f ms, backward %.2f ms, fwd+bwd %.2f ms "
        "(%.0f/s); "
        "device memory %.0f B/Gaussian (peak over the runs)\n",
        name, model.size(), DeviceName(device).c_str(), 1e3 * Median(fwd),
        1e3 * Median(bwd), 1e3 * Median(both), 1.0 / Median(both),
        device_bytes / std::max<size_t>(1, model.size()));
    return Median(both);
  }
  // Splat-pixel pairs the blending loops visit: list entries x 256.
  const double pairs = 256.0 * ctx->bins.ids.size();
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
      "splat-pixel = tile-list entries x 256\n",
      opt.threads, opt.repeats, opt.sh_degree, DeviceName(opt.device).c_str());
  RenderOptions full;
  if (opt.scenes == 1000) {
    const RenderCamera hd = BenchCamera(4);
    const GaussianModel huge =
        SyntheticScene(hd, 1000000, opt.sh_degree, true, 3);
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
