// 1D quantiser and k-means for codebook formats (see kmeans.h).
#include "gaussian/formats/kmeans.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <nanoflann.hpp>
#include <numeric>
#include <random>

#include "gaussian/util/error.h"

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

namespace {

// Weighted points on a line, ascending: what the 1D quantiser clusters.
struct Atoms {
  std::vector<double> x, w;
};

// Distinct values beyond which the quantiser clusters equal-width bins
// instead (a bin is 1/65536 of the range: far below a 256-entry step).
constexpr size_t kMaxAtoms = 65536;
// Largest k x atoms table the exact solution fills (4 bytes an entry);
// SOG's 256-entry codebooks need at most 256 x 65536.
constexpr size_t kMaxExactTable = size_t(1) << 24;

// `sorted` as atoms: each distinct value with its count, or, with more than
// kMaxAtoms distinct values, each non-empty bin's mean with its count.
Atoms MakeAtoms(const std::vector<float>& sorted) {
  Atoms atoms;
  for (size_t i = 0; i < sorted.size();) {
    size_t end = i;
    while (end < sorted.size() && sorted[end] == sorted[i]) ++end;
    atoms.x.push_back(sorted[i]);
    atoms.w.push_back(double(end - i));
    i = end;
  }
  if (atoms.x.size() <= kMaxAtoms) return atoms;
  const double lo = sorted.front(),
               width = (double(sorted.back()) - lo) / kMaxAtoms;
  Atoms bins;
  for (size_t i = 0; i < sorted.size();) {
    const size_t bin =
        std::min(kMaxAtoms - 1, size_t((sorted[i] - lo) / width));
    double sum = 0, count = 0;
    while (i < sorted.size() &&
           std::min(kMaxAtoms - 1, size_t((sorted[i] - lo) / width)) == bin) {
      sum += sorted[i++];
      ++count;
    }
    bins.x.push_back(sum / count);
    bins.w.push_back(count);
  }
  return bins;
}

// Within-cluster sums of squares of atom ranges [a, b) in O(1) from prefix
// sums (of values centred on their mean, against cancellation).
class RangeCost {
 public:
  explicit RangeCost(const Atoms& atoms) : w_(1, 0), s_(1, 0), q_(1, 0) {
    double mean = 0, total = 0;
    for (size_t i = 0; i < atoms.x.size(); ++i) {
      mean += atoms.w[i] * atoms.x[i];
      total += atoms.w[i];
    }
    centre_ = mean / total;
    for (size_t i = 0; i < atoms.x.size(); ++i) {
      const double x = atoms.x[i] - centre_;
      w_.push_back(w_.back() + atoms.w[i]);
      s_.push_back(s_.back() + atoms.w[i] * x);
      q_.push_back(q_.back() + atoms.w[i] * x * x);
    }
  }
  double operator()(size_t a, size_t b) const {
    const double s = s_[b] - s_[a];
    return std::max(0.0, q_[b] - q_[a] - s * s / (w_[b] - w_[a]));
  }
  double Mean(size_t a, size_t b) const {
    return centre_ + (s_[b] - s_[a]) / (w_[b] - w_[a]);
  }

 private:
  std::vector<double> w_, s_, q_;
  double centre_ = 0;
};

// The partition of m atoms into k contiguous clusters (k <= m) with the
// least within-cluster sum of squares: k-means' objective, solved exactly
// (in 1D optimal clusters are contiguous) by dynamic programming as in
// Wang and Song's Ckmeans.1d.dp, each layer by divide and conquer over its
// monotone split points. Returns each cluster's first atom, ascending.
std::vector<size_t> OptimalSplits(const RangeCost& cost, size_t m, size_t k) {
  // best[i]: least cost of atoms [0, i) in the clusters so far.
  std::vector<double> best(m + 1), next(m + 1);
  for (size_t i = 1; i <= m; ++i) best[i] = cost(0, i);
  // split[c][i]: first atom of the last cluster of [0, i) in c + 1 clusters.
  std::vector<std::vector<uint32_t>> split(k);
  split[0].assign(m + 1, 0);
  for (size_t c = 1; c < k; ++c) {
    std::vector<uint32_t>& at = split[c];
    at.assign(m + 1, 0);
    // Fills next[i] for i in [lo, hi] knowing its split lies in [from, to].
    std::function<void(size_t, size_t, size_t, size_t)> solve =
        [&](size_t lo, size_t hi, size_t from, size_t to) {
          if (lo > hi) return;
          const size_t mid = lo + (hi - lo) / 2;
          double least = INFINITY;
          size_t arg = from;
          for (size_t j = from; j <= std::min(to, mid - 1); ++j) {
            const double v = best[j] + cost(j, mid);
            if (v < least) least = v, arg = j;
          }
          next[mid] = least;
          at[mid] = uint32_t(arg);
          if (mid > lo) solve(lo, mid - 1, from, arg);
          solve(mid + 1, hi, arg, to);
        };
    solve(c + 1, m, c, m - 1);
    std::swap(best, next);
  }
  std::vector<size_t> starts(k);
  size_t end = m;
  for (size_t c = k; c-- > 0;) {
    starts[c] = split[c][end];
    end = starts[c];
  }
  return starts;
}

// Lloyd's algorithm from the k quantiles: the fallback for codebooks too
// large for the exact solution's k x m table.
std::vector<double> LloydCentres(const std::vector<float>& sorted, size_t k) {
  const size_t n = sorted.size();
  std::vector<double> prefix(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + sorted[i];
  std::vector<double> centres;
  for (size_t j = 0; j < k; ++j) {
    centres.push_back(sorted[std::min(n - 1, size_t((j + 0.5) * n / k))]);
  }
  centres.erase(std::unique(centres.begin(), centres.end()), centres.end());
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
  return centres;
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
  const Atoms atoms = MakeAtoms(sorted);
  const size_t m = atoms.x.size();
  if (m <= size_t(k)) {
    codebook->assign(atoms.x.begin(), atoms.x.end());
  } else if (size_t(k) * m <= kMaxExactTable) {
    const RangeCost cost(atoms);
    const std::vector<size_t> starts = OptimalSplits(cost, m, size_t(k));
    for (size_t c = 0; c < starts.size(); ++c) {
      const size_t end = c + 1 < starts.size() ? starts[c + 1] : m;
      codebook->push_back(float(cost.Mean(starts[c], end)));
    }
  } else {
    const std::vector<double> centres = LloydCentres(sorted, size_t(k));
    codebook->assign(centres.begin(), centres.end());
  }
  std::sort(codebook->begin(), codebook->end());
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
