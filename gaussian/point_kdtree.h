// A k-d tree over an N x 3 float array (nanoflann), for neighbour queries on
// SfM points and Gaussian means.
#pragma once

#include <cstdint>
#include <nanoflann.hpp>
#include <vector>

namespace watergs {

// nanoflann's view of an N x 3 float array (x0 y0 z0 x1 ...).
struct PointCloudAdaptor {
  const std::vector<float>& xyz;
  size_t kdtree_get_point_count() const { return xyz.size() / 3; }
  float kdtree_get_pt(size_t i, size_t dim) const { return xyz[3 * i + dim]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

// Squared Euclidean distances; build as PointKdTree(3, adaptor, params).
using PointKdTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, PointCloudAdaptor>, PointCloudAdaptor,
    3, uint32_t>;

}  // namespace watergs
