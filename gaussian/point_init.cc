// Initial Gaussians from a sparse SfM point cloud (see point_init.h).
#include "gaussian/point_init.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "gaussian/point_kdtree.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

// Inria's lower bound on the squared neighbour distance before the log.
constexpr float kMinSquaredDistance = 1e-7f;
// Squared distance given to a point with no neighbour at all.
constexpr float kLonePointSquaredDistance = 1.f;
// Initial opacity (before the sigmoid) in Inria's initialisation.
constexpr float kInitialOpacity = 0.1f;

}  // namespace

std::vector<float> MeanSquaredNeighbourDistances(const std::vector<float>& xyz,
                                                 int k) {
  const size_t n = xyz.size() / 3;
  std::vector<float> result(n, kLonePointSquaredDistance);
  if (n < 2 || k < 1) return result;
  const size_t neighbours = std::min<size_t>(k, n - 1);
  const PointCloudAdaptor cloud{xyz};
  const PointKdTree tree(3, cloud,
                         nanoflann::KDTreeSingleIndexAdaptorParams(10));
#pragma omp parallel
  {
    // One more than wanted: the query point finds itself (or a duplicate).
    std::vector<uint32_t> index(neighbours + 1);
    std::vector<float> dist2(neighbours + 1);
#pragma omp for schedule(static)
    for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
      const size_t found = tree.knnSearch(&xyz[3 * i], neighbours + 1,
                                          index.data(), dist2.data());
      // Drop the point itself; if duplicates pushed it out of the list, drop
      // the farthest instead, which then also lies at distance 0.
      size_t self = found - 1;
      for (size_t j = 0; j < found; ++j) {
        if (index[j] == static_cast<uint32_t>(i)) self = j;
      }
      double sum = 0;
      for (size_t j = 0; j < found; ++j) sum += j == self ? 0.0 : dist2[j];
      result[i] = static_cast<float>(sum / static_cast<double>(found - 1));
    }
  }
  return result;
}

GaussianModel InitGaussiansFromPoints(const std::vector<float>& xyz,
                                      const std::vector<float>& rgb,
                                      int sh_degree) {
  if (xyz.size() % 3 != 0 || rgb.size() != xyz.size()) {
    Fail("InitGaussiansFromPoints: " + std::to_string(xyz.size()) +
         " coordinates and " + std::to_string(rgb.size()) +
         " colour values do not form N x 3 arrays");
  }
  if (sh_degree < 0 || sh_degree > 3) Fail("SH degree must be 0-3");
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (!std::isfinite(xyz[i]))
      Fail("point " + std::to_string(i / 3) + " is not finite");
  }
  GaussianModel model;
  model.sh_degree = sh_degree;
  const size_t n = xyz.size() / 3;
  model.Resize(n);
  model.means = xyz;
  for (size_t i = 0; i < 3 * n; ++i) model.sh_dc[i] = RgbToShDc(rgb[i]);
  const std::vector<float> dist2 = MeanSquaredNeighbourDistances(xyz, 3);
  const float opacity_logit =
      std::log(kInitialOpacity / (1.f - kInitialOpacity));
  for (size_t i = 0; i < n; ++i) {
    const float log_scale =
        std::log(std::sqrt(std::max(dist2[i], kMinSquaredDistance)));
    std::fill_n(&model.log_scales[3 * i], 3, log_scale);
    model.quats[4 * i] = 1.f;  // w first; x, y, z stay 0
    model.opacity_logits[i] = opacity_logit;
  }
  return model;
}

}  // namespace watergs
