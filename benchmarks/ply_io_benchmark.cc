// Benchmark of 3DGS PLY I/O: write (Inria layout, atomic) and read times and
// throughput for a random SH-degree-3 model. Usage:
// ply_io_benchmark [num_gaussians=300000] [repeats=5] [folder=/tmp]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "benchmarks/benchmark_util.h"
#include "gaussian/formats/ply_io.h"

namespace {

using watergs::bench::MedianSeconds;

}  // namespace

int main(int argc, char** argv) {
  const size_t n = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 300000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  const std::string folder = argc > 3 ? argv[3] : "/tmp";
  watergs::GaussianModel model;
  model.sh_degree = 3;
  model.Resize(n);
  std::mt19937 rng(1);
  std::normal_distribution<float> normal;
  for (auto* v : {&model.means, &model.log_scales, &model.quats,
                  &model.opacity_logits, &model.sh_dc, &model.sh_rest}) {
    for (float& x : *v) x = normal(rng);
  }
  const std::string path = folder + "/watergs_ply_io_benchmark.ply";
  const double write =
      MedianSeconds(repeats, [&] { watergs::WritePly(path, model); });
  const double mb = std::filesystem::file_size(path) / 1e6;
  size_t read_count = 0;
  const double read = MedianSeconds(
      repeats, [&] { read_count = watergs::ReadPly(path).model.size(); });
  std::filesystem::remove(path);
  std::printf(
      "%zu Gaussians, SH 3, %.1f MB: write %.3f s (%.0f MB/s), read %.3f s "
      "(%.0f MB/s), medians of %d\n",
      n, mb, write, mb / write, read, mb / read, repeats);
  return read_count == n ? 0 : 1;
}
