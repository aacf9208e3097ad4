// Timing helpers shared by the benchmarks: medians of repeated runs, the
// figure the README quotes (this machine is noisy; means are not).
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace watergs::bench {

// Median of `values` (mean of the middle two for an even count).
inline double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const size_t m = values.size() / 2;
  return values.size() % 2 ? values[m] : 0.5 * (values[m - 1] + values[m]);
}

// Median wall time in seconds of `repeats` calls of f, after one untimed
// warm-up call (allocations, caches, page faults).
template <typename F>
double MedianSeconds(int repeats, F&& f) {
  using Clock = std::chrono::steady_clock;
  f();
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    const auto start = Clock::now();
    f();
    times.push_back(
        std::chrono::duration<double>(Clock::now() - start).count());
  }
  return Median(times);
}

}  // namespace watergs::bench
