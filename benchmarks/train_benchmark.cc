// Training-iteration benchmark on a COLMAP workspace (default: the demo
// scene): per-stage times of a full iteration (forward, loss, backward,
// Adam) at the initial SfM-point model and at a model grown to ~100k
// Gaussians by splitting, density-control cost, iterations/s (medians),
// and training-state bytes per Gaussian.
//
// Usage: train_benchmark [--workspace_path WS] [--iterations 30]
//                        [--grown 100000] [--num_threads 0] [--json out.json]
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "gaussian/density_strategy.h"
#include "gaussian/device.h"
#include "gaussian/loss.h"
#include "gaussian/point_init.h"
#include "gaussian/trainer.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"

namespace {

// Device of the rasterizer under test (--device; the CPU by default).
watergs::Device g_device = watergs::Device::kCpu;

using namespace watergs;
using Clock = std::chrono::steady_clock;

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Splits every Gaussian into two samples (scale / 1.6) until the model has
// at least `target`, then keeps a random `target` of them.
GaussianModel Grow(GaussianModel model, size_t target, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal;
  while (model.size() < target && model.size() > 0) {
    GaussianModel next;
    next.sh_degree = model.sh_degree;
    for (size_t i = 0; i < model.size(); ++i) {
      for (int k = 0; k < 2; ++k) {
        next.AppendFrom(model, i);
        const size_t j = next.size() - 1;
        for (int a = 0; a < 3; ++a) {
          const float s = std::exp(model.log_scales[3 * i + a]);
          next.means[3 * j + a] += normal(rng) * s;
          next.log_scales[3 * j + a] -= std::log(1.6f);
        }
      }
    }
    model = std::move(next);
  }
  std::vector<size_t> order(model.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<bool> keep(model.size(), false);
  for (size_t k = 0; k < std::min(target, order.size()); ++k) {
    keep[order[k]] = true;
  }
  model.Filter(keep);
  return model;
}

struct StageTimes {
  double forward = 0, loss = 0, backward = 0, adam = 0, total = 0;
  // Process CPU seconds per iteration (all threads): on a shared machine
  // the 1-thread CPU time is the steadiest figure.
  double cpu = 0;
  // Process CPU seconds per stage: forward, loss, backward, density, Adam.
  std::array<double, 5> stage_cpu = {0, 0, 0, 0, 0};
};

double ProcessCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

// Runs `warmup` + `count` iterations without density control; medians.
StageTimes TimeIterations(const TrainingViews& views,
                          const std::vector<size_t>& train, GaussianModel model,
                          double extent, int active_sh, int warmup, int count,
                          bool half_moments = false) {
  TrainerOptions options;
  options.adam.half_moments = half_moments;
  options.iterations = 1 << 30;
  // Raise the SH degree once per warm-up iteration up to active_sh.
  options.sh_increase_interval = active_sh > 0 ? 1 : 0;
  model.sh_degree = std::max(model.sh_degree, active_sh);
  Trainer trainer(options, views, train, model, extent,
                  MakeRasterizer(g_device), MakeFixedDensityStrategy());
  std::vector<double> f, l, b, a, t, cpu;
  std::array<std::vector<double>, 5> stage_cpu;
  warmup = std::max(warmup, active_sh);
  for (int i = 0; i < warmup + count; ++i) {
    const double cpu_start = ProcessCpuSeconds();
    const IterationStats s = trainer.Step();
    if (i < warmup) continue;
    cpu.push_back(ProcessCpuSeconds() - cpu_start);
    for (int k = 0; k < 5; ++k) stage_cpu[k].push_back(s.cpu_s[k]);
    f.push_back(s.forward_s);
    l.push_back(s.loss_s);
    b.push_back(s.backward_s);
    a.push_back(s.adam_s);
    t.push_back(s.forward_s + s.loss_s + s.backward_s + s.density_s + s.adam_s);
  }
  StageTimes times{Median(f), Median(l), Median(b),
                   Median(a), Median(t), Median(cpu)};
  for (int k = 0; k < 5; ++k) times.stage_cpu[k] = Median(stage_cpu[k]);
  return times;
}

// Cost of Inria's density control: an accumulate-only call and a
// densify-and-prune call on `model` with gradients from one real backward.
std::pair<double, double> TimeDensity(const TrainingViews& views,
                                      const std::vector<size_t>& train,
                                      const GaussianModel& model,
                                      double extent) {
  TrainerOptions options;
  options.iterations = 10;
  Trainer trainer(options, views, train, model, extent,
                  MakeRasterizer(g_device), MakeFixedDensityStrategy());
  // Gradients of one view.
  GaussianGradients grads;
  ImageRGB image, grad;
  std::unique_ptr<RenderContext> context;
  trainer.rasterizer().Forward(model, views.Camera(train[0]), RenderOptions{},
                               &image, &context);
  TrainingLoss loss;
  loss.Evaluate(image, *views.Image(train[0]), &grad);
  trainer.rasterizer().Backward(model, *context, grad, &grads);
  std::vector<double> accumulate, densify;
  for (int rep = 0; rep < 5; ++rep) {
    GaussianModel m = model;
    Adam adam(AdamOptions{}, extent);
    adam.Init(m);
    auto strategy = MakeInriaDensityStrategy(DensityOptions{}, extent);
    strategy->Init(m);
    auto t0 = Clock::now();
    strategy->PostBackward(599, grads, nullptr, &m, &adam);
    auto t1 = Clock::now();
    strategy->PostBackward(600, grads, nullptr, &m, &adam);
    auto t2 = Clock::now();
    accumulate.push_back(std::chrono::duration<double>(t1 - t0).count());
    densify.push_back(std::chrono::duration<double>(t2 - t1).count());
  }
  return {Median(accumulate), Median(densify)};
}

double TimeLoss(const ImageRGB& truth, int reps) {
  ImageRGB render = truth, grad;
  for (size_t i = 0; i < render.data.size(); ++i) {
    render.data[i] = 0.9f * render.data[i] + 0.05f;
  }
  TrainingLoss loss;
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    auto t0 = Clock::now();
    loss.Evaluate(render, truth, &grad);
    t.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  return Median(t);
}

void PrintStages(const char* label, size_t n, const StageTimes& s) {
  std::printf(
      "%-10s %7zu Gaussians: forward %7.2f ms  loss %6.2f ms  backward %7.2f "
      "ms  adam %6.2f ms  | iteration %7.2f ms = %6.1f it/s (CPU %7.2f "
      "ms)\n",
      label, n, 1e3 * s.forward, 1e3 * s.loss, 1e3 * s.backward, 1e3 * s.adam,
      1e3 * s.total, s.total > 0 ? 1.0 / s.total : 0.0, 1e3 * s.cpu);
  std::printf(
      "%-10s CPU per stage: forward %7.2f ms  loss %6.2f ms  backward %7.2f "
      "ms  adam %6.2f ms\n",
      "", 1e3 * s.stage_cpu[0], 1e3 * s.stage_cpu[1], 1e3 * s.stage_cpu[2],
      1e3 * s.stage_cpu[4]);
}

nlohmann::json StagesJson(size_t n, const StageTimes& s) {
  return {{"num_gaussians", n},
          {"forward_ms", 1e3 * s.forward},
          {"loss_ms", 1e3 * s.loss},
          {"backward_ms", 1e3 * s.backward},
          {"adam_ms", 1e3 * s.adam},
          {"iteration_ms", 1e3 * s.total},
          {"iterations_per_second", s.total > 0 ? 1.0 / s.total : 0.0},
          {"cpu_ms_per_iteration", 1e3 * s.cpu},
          {"cpu_ms_forward", 1e3 * s.stage_cpu[0]},
          {"cpu_ms_loss", 1e3 * s.stage_cpu[1]},
          {"cpu_ms_backward", 1e3 * s.stage_cpu[2]},
          {"cpu_ms_adam", 1e3 * s.stage_cpu[4]}};
}

}  // namespace

int main(int argc, char** argv) {
  std::string workspace_path =
      std::string(WATERGS_SOURCE_DIR) + "/datasets_scripts/demo_scene";
  std::string json_path, device_text = "cpu";
  int iterations = 30, num_threads = 0;
  size_t grown = 100000;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--workspace_path")
      workspace_path = value;
    else if (key == "--iterations")
      iterations = std::stoi(value);
    else if (key == "--grown")
      grown = std::stoul(value);
    else if (key == "--num_threads")
      num_threads = std::stoi(value);
    else if (key == "--json")
      json_path = value;
    else if (key == "--device")
      device_text = value;
    else {
      std::fprintf(stderr, "unknown option %s\n", key.c_str());
      return 1;
    }
  }
  if (num_threads > 0) omp_set_num_threads(num_threads);
  try {
    g_device = ResolveDevice(device_text);
    WorkspaceOptions wo;
    wo.workspace_path = workspace_path;
    const Workspace workspace = Workspace::Open(wo);
    const WorkspaceViews views(workspace);
    const std::vector<size_t> train = workspace.TrainViews(false);
    std::vector<float> xyz, rgb;
    workspace.PointCloud(&xyz, &rgb);
    const GaussianModel init = InitGaussiansFromPoints(xyz, rgb, 3);
    const double extent = workspace.SceneExtent();
    const RenderCamera cam = views.Camera(train[0]);
    std::printf(
        "train_benchmark: %s, %zu views %dx%d, %d threads, rasterizer on %s, "
        "%d timed iterations (medians)\n",
        workspace_path.c_str(), train.size(), cam.width, cam.height,
        omp_get_max_threads(), DeviceName(g_device).c_str(), iterations);

    const double loss_s = TimeLoss(*views.Image(train[0]), 2 * iterations);
    std::printf("loss (L1 + SSIM, value and gradient) at %dx%d: %.2f ms\n",
                cam.width, cam.height, 1e3 * loss_s);
    // Views are cached by the workspace after the first pass.
    const StageTimes initial =
        TimeIterations(views, train, init, extent, 0, 5, iterations);
    PrintStages("initial", init.size(), initial);
    const GaussianModel big = Grow(init, grown, 1);
    const StageTimes grown_times =
        TimeIterations(views, train, big, extent, 3, 3, iterations);
    PrintStages("grown/SH3", big.size(), grown_times);
    const StageTimes half_times =
        TimeIterations(views, train, big, extent, 3, 3, iterations, true);
    PrintStages("bfloat16", big.size(), half_times);
    const auto [accumulate_s, densify_s] =
        TimeDensity(views, train, big, extent);
    std::printf(
        "density control at %zu Gaussians: accumulate %.2f ms, "
        "densify+prune step %.2f ms (every 100 iterations)\n",
        big.size(), 1e3 * accumulate_s, 1e3 * densify_s);

    TrainerOptions options;
    Trainer sizing(options, views, train, init, extent,
                   MakeRasterizer(g_device));
    const size_t state_bytes = sizing.StateBytesPerGaussian();
    options.adam.half_moments = true;
    Trainer half(options, views, train, init, extent, MakeRasterizer(g_device));
    const size_t half_bytes = half.StateBytesPerGaussian();
    options.adam.half_moments = false;
    options.adam.compact_moments = true;
    Trainer compact(options, views, train, init, extent,
                    MakeRasterizer(g_device));
    const size_t compact_bytes = compact.StateBytesPerGaussian();
    std::printf(
        "training state per Gaussian (SH degree 3): %zu bytes with Inria's "
        "Adam (float32 moments), %zu with --moment_precision bfloat16, %zu "
        "with --compact_optimizer\n",
        state_bytes, half_bytes, compact_bytes);
    if (!json_path.empty()) {
      nlohmann::json j;
      j["workspace"] = workspace_path;
      j["threads"] = omp_get_max_threads();
      j["device"] = DeviceName(g_device);
      j["width"] = cam.width;
      j["height"] = cam.height;
      j["loss_ms"] = 1e3 * loss_s;
      j["initial"] = StagesJson(init.size(), initial);
      j["grown"] = StagesJson(big.size(), grown_times);
      j["density_accumulate_ms"] = 1e3 * accumulate_s;
      j["density_densify_ms"] = 1e3 * densify_s;
      j["state_bytes_per_gaussian"] = state_bytes;
      j["state_bytes_per_gaussian_compact"] = compact_bytes;
      j["state_bytes_per_gaussian_bfloat16"] = half_bytes;
      j["grown_bfloat16"] = StagesJson(big.size(), half_times);
      // Which build and options measured these figures, as the CLI's JSON.
      j["provenance"] = ProgramProvenance(argc, argv);
      AtomicWriteFile(json_path, j.dump(2) + "\n");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
