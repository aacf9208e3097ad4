#include "plugin/sift_matching.h"

#include <algorithm>
#include <cmath>

namespace watergs {
namespace {

// The two largest dot products of one descriptor and where the largest is.
struct BestTwo {
  // COLMAP starts both at 0: a dot product of 0 or less is never a
  // neighbour, and a missing second one reads as pi/2.
  float best = 0, second = 0;
  int at = -1;
  void Add(float dot, int index) {
    if (dot > best) {
      second = best, best = dot, at = index;
    } else if (dot > second) {
      second = dot;
    }
  }
};

// The neighbour of `b` if it passes the distance and ratio tests, else -1.
int Accepted(const BestTwo& b, const SiftMatchOptions& o) {
  if (b.at < 0) return -1;
  const double best = SiftAngle(b.best), second = SiftAngle(b.second);
  if (best > o.max_distance) return -1;
  if (!(best < o.max_ratio * second)) return -1;
  return b.at;
}

}  // namespace

double SiftAngle(double dot) {
  return std::acos(std::min(dot / (512.0 * 512.0), 1.0));
}

FeatureMatches MatchSiftDescriptors(const SiftDescriptors& a,
                                    const SiftDescriptors& b,
                                    const SiftMatchOptions& options) {
  FeatureMatches matches;
  const int na = int(a.rows()), nb = int(b.rows());
  if (na == 0 || nb == 0) return matches;
  // Per thread, reused: a fresh 16 MB product per pair spent a tenth of the
  // time in page faults.
  thread_local Eigen::MatrixXf fa, fb, dots;
  fa = a.cast<float>(), fb = b.cast<float>();
  // Column i: the dot products of a's descriptor i with each of b's.
  dots.resize(nb, na);
  dots.noalias() = fb * fa.transpose();
  std::vector<BestTwo> of_a(na);
  // b's neighbours in a, as arrays (branch-free updates vectorise).
  std::vector<float> best(nb, 0.f), second(nb, 0.f);
  std::vector<int> at(nb, -1);
  for (int i = 0; i < na; ++i) {
    const float* column = dots.col(i).data();
    for (int j = 0; j < nb; ++j) of_a[i].Add(column[j], j);
    for (int j = 0; j < nb; ++j) {
      const float v = column[j];
      const bool better = v > best[j];
      second[j] = better ? best[j] : std::max(second[j], v);
      at[j] = better ? i : at[j];
      best[j] = better ? v : best[j];
    }
  }
  for (int i = 0; i < na; ++i) {
    const int j = Accepted(of_a[i], options);
    if (j < 0) continue;
    if (options.cross_check) {
      BestTwo of_b;
      of_b.best = best[j], of_b.second = second[j], of_b.at = at[j];
      if (Accepted(of_b, options) != i) continue;
    }
    matches.emplace_back(i, j);
  }
  return matches;
}

std::vector<std::pair<int, int>> ExhaustivePairs(int n) {
  return SequentialPairs(n, n, false);
}

std::vector<std::pair<int, int>> SequentialPairs(int n, int overlap,
                                                 bool quadratic) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n && j < i + overlap; ++j) pairs.emplace_back(i, j);
    for (int k = 0; quadratic && k < std::min(overlap, 30); ++k) {
      const int64_t j = i + (int64_t(1) << k);
      if (j >= i + overlap && j < n) pairs.emplace_back(i, int(j));
    }
  }
  return pairs;
}

}  // namespace watergs
