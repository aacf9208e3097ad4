// 1D quantiser and k-means for codebook formats (see kmeans.h).
#include "gaussian/kmeans.h"

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <numeric>
#include <random>

#include "gaussian/error.h"

namespace watergs {
namespace {

// nanoflann's view of n points of `dim` floats.
struct RowsAdaptor {
  const std::vector<float>& rows;
  size_t dim;
  size_t kdtree_get_point_count() const { return rows.size() / dim; }
  float kdtree_get_pt(size_t i, size_t d) const { return rows[i * dim + d]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

using RowsKdTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, RowsAdaptor>, RowsAdaptor, -1,
    uint32_t>;

// Labels every point with its nearest centroid; dist2[i] its squared
// distance. Points are independent, so the result is the same for any
// thread count.
void AssignNearest(const std::vector<float>& points, size_t dim,
                   const std::vector<float>& centroids,
                   std::vector<uint32_t>* labels, std::vector<float>* dist2) {
  const RowsAdaptor adaptor{centroids, dim};
  const RowsKdTree tree(int(dim), adaptor,
                        nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const size_t n = points.size() / dim;
  labels->resize(n);
  dist2->resize(n);
#pragma omp parallel for schedule(static) if (n > 4096)
  for (int64_t i = 0; i < int64_t(n); ++i) {
    uint32_t index = 0;
    float d2 = 0.f;
    tree.knnSearch(&points[size_t(i) * dim], 1, &index, &d2);
    (*labels)[i] = index;
    (*dist2)[i] = d2;
  }
}

}  // namespace

void Quantize1d(const std::vector<float>& values, int k,
                std::vector<float>* codebook, std::vector<uint32_t>* labels) {
  if (k < 1 || k > 65536) Fail("Quantize1d: k must be in [1, 65536]");
  codebook->clear();
  labels->assign(values.size(), 0);
  if (values.empty()) return;
  std::vector<float> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  const size_t n = sorted.size();
  // Prefix sums in double: a cluster's mean is two look-ups.
  std::vector<double> prefix(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + sorted[i];
  std::vector<double> centres;
  for (int j = 0; j < k; ++j) {
    centres.push_back(sorted[std::min(n - 1, size_t((j + 0.5) * n / k))]);
  }
  centres.erase(std::unique(centres.begin(), centres.end()), centres.end());
  // Lloyd: clusters are the runs of `sorted` between midpoints; converges
  // in a few dozen rounds for the 256-entry codebooks SOG uses.
  for (int round = 0; round < 100; ++round) {
    std::vector<double> next;
    size_t begin = 0;
    for (size_t j = 0; j < centres.size(); ++j) {
      size_t end = n;
      if (j + 1 < centres.size()) {
        const double mid = 0.5 * (centres[j] + centres[j + 1]);
        end =
            size_t(std::upper_bound(sorted.begin() + begin, sorted.end(), mid) -
                   sorted.begin());
      }
      if (end > begin) {
        next.push_back((prefix[end] - prefix[begin]) / double(end - begin));
      }
      begin = end;
    }
    const bool same = next == centres;
    centres = std::move(next);
    if (same) break;
  }
  codebook->assign(centres.begin(), centres.end());
  // float rounding may make neighbours equal; equal entries are harmless.
  for (size_t i = 0; i < values.size(); ++i) {
    const auto it =
        std::lower_bound(codebook->begin(), codebook->end(), values[i]);
    size_t best = size_t(it - codebook->begin());
    if (best == codebook->size() ||
        (best > 0 &&
         values[i] - (*codebook)[best - 1] <= (*codebook)[best] - values[i])) {
      best = best == 0 ? 0 : best - 1;
    }
    (*labels)[i] = uint32_t(best);
  }
}

void KMeans(const std::vector<float>& points, int dim, size_t k, int iterations,
            uint64_t seed, std::vector<float>* centroids,
            std::vector<uint32_t>* labels,
            const std::function<void(int)>& on_round) {
  if (dim < 1 || points.size() % size_t(dim) != 0) {
    Fail("KMeans: points are not rows of dim floats");
  }
  const size_t d = size_t(dim);
  const size_t n = points.size() / d;
  if (k > n) Fail("KMeans: more clusters than points");
  if (k == 0 || n == 0) {
    centroids->clear();
    labels->assign(n, 0);
    return;
  }
  // k distinct points as seeds (a partial Fisher-Yates shuffle).
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::mt19937_64 rng(seed);
  for (size_t i = 0; i < k; ++i) {
    // rng() % range, not std::uniform_int_distribution: the same seeds with
    // every standard library (the bias is 2^-40 at most).
    std::swap(order[i], order[i + size_t(rng() % uint64_t(n - i))]);
  }
  centroids->resize(k * d);
  for (size_t c = 0; c < k; ++c) {
    std::copy_n(&points[order[c] * d], d, &(*centroids)[c * d]);
  }
  std::vector<float> dist2;
  for (int round = 0; round < iterations; ++round) {
    AssignNearest(points, d, *centroids, labels, &dist2);
    std::vector<double> sums(k * d, 0.0);
    std::vector<size_t> counts(k, 0);
    for (size_t i = 0; i < n; ++i) {
      const size_t c = (*labels)[i];
      ++counts[c];
      for (size_t j = 0; j < d; ++j) sums[c * d + j] += points[i * d + j];
    }
    // Empty clusters restart at the worst-served points.
    std::vector<uint32_t> worst;
    for (size_t c = 0; c < k; ++c) {
      if (counts[c] > 0) {
        for (size_t j = 0; j < d; ++j) {
          (*centroids)[c * d + j] = float(sums[c * d + j] / double(counts[c]));
        }
        continue;
      }
      if (worst.empty()) {
        worst.resize(n);
        std::iota(worst.begin(), worst.end(), 0u);
        std::stable_sort(
            worst.begin(), worst.end(),
            [&](uint32_t a, uint32_t b) { return dist2[a] > dist2[b]; });
        worst.resize(std::min(n, k));
        std::reverse(worst.begin(), worst.end());
      }
      std::copy_n(&points[worst.back() * d], d, &(*centroids)[c * d]);
      worst.pop_back();
    }
    if (on_round) on_round(round + 1);
  }
  AssignNearest(points, d, *centroids, labels, &dist2);
}

}  // namespace watergs
