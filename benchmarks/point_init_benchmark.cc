// Benchmark of the initialisation k-NN: nanoflann k-d tree vs an O(N^2)
// brute-force search, on random points (default 100k), 1 thread and all
// threads; also checks that both give the same distances.
// Usage: point_init_benchmark [num_points=100000] [repeats=5]
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>
#include <vector>

#include "gaussian/point_init.h"

namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
      .count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// Mean squared distance to the 3 nearest other points, by scanning all pairs.
std::vector<float> BruteForce3Nn(const std::vector<float>& xyz) {
  const int64_t n = static_cast<int64_t>(xyz.size() / 3);
  std::vector<float> result(n);
#pragma omp parallel for schedule(dynamic, 64)
  for (int64_t i = 0; i < n; ++i) {
    float best[3] = {INFINITY, INFINITY, INFINITY};
    const float xi = xyz[3 * i], yi = xyz[3 * i + 1], zi = xyz[3 * i + 2];
    for (int64_t j = 0; j < n; ++j) {
      const float dx = xyz[3 * j] - xi, dy = xyz[3 * j + 1] - yi,
                  dz = xyz[3 * j + 2] - zi;
      const float d2 = dx * dx + dy * dy + dz * dz;
      if (d2 >= best[2] || j == i) continue;
      if (d2 < best[1]) {
        best[2] = best[1];
        if (d2 < best[0]) {
          best[1] = best[0];
          best[0] = d2;
        } else {
          best[1] = d2;
        }
      } else {
        best[2] = d2;
      }
    }
    result[i] = (best[0] + best[1] + best[2]) / 3.f;
  }
  return result;
}

struct Timing {
  // Median wall-clock seconds.
  double wall;
  // Median process CPU seconds (all threads); robust to a loaded machine.
  double cpu;
};

template <typename F>
Timing MedianTime(int repeats, F&& f) {
  std::vector<double> walls, cpus;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    f();
    cpus.push_back(double(std::clock() - cpu_start) / CLOCKS_PER_SEC);
    walls.push_back(Seconds(start));
  }
  return {Median(walls), Median(cpus)};
}

}  // namespace

int main(int argc, char** argv) {
  const size_t n = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 100000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> uniform(-10.f, 10.f);
  std::vector<float> xyz(3 * n);
  for (float& v : xyz) v = uniform(rng);
  const int max_threads = omp_get_max_threads();
  std::printf("points: %zu, repeats: %d (brute force: 1), threads: 1 and %d\n",
              n, repeats, max_threads);

  std::vector<float> tree_result, brute_result;
  for (int threads : {1, max_threads}) {
    omp_set_num_threads(threads);
    const Timing tree = MedianTime(repeats, [&] {
      tree_result = watergs::MeanSquaredNeighbourDistances(xyz, 3);
    });
    const Timing brute =
        MedianTime(1, [&] { brute_result = BruteForce3Nn(xyz); });
    std::printf(
        "threads %d: nanoflann wall %.4f s / cpu %.4f s (medians), brute force "
        "wall %.2f s / cpu %.2f s, speed-up %.0fx wall, %.0fx cpu\n",
        threads, tree.wall, tree.cpu, brute.wall, brute.cpu,
        brute.wall / tree.wall, brute.cpu / tree.cpu);
    if (threads == max_threads) break;
  }
  double worst = 0;
  for (size_t i = 0; i < n; ++i) {
    worst = std::max(worst, std::abs(double(tree_result[i]) - brute_result[i]) /
                                std::max(1e-12, double(brute_result[i])));
  }
  std::printf("max relative difference nanoflann vs brute force: %.3g\n",
              worst);
  const Timing init = MedianTime(repeats, [&] {
    watergs::InitGaussiansFromPoints(xyz, std::vector<float>(xyz.size(), .5f),
                                     3);
  });
  std::printf(
      "InitGaussiansFromPoints (SH degree 3, %d threads): wall %.4f s, cpu "
      "%.4f s\n",
      max_threads, init.wall, init.cpu);
  return worst < 1e-4 ? 0 : 1;
}
