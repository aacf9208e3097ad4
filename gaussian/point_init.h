// Initial Gaussians from a sparse SfM point cloud, as Inria's 3DGS does it:
// one isotropic Gaussian per point, sized by its 3 nearest neighbours.
#pragma once

#include <vector>

#include "gaussian/gaussian_model.h"

namespace watergs {

// xyz N x 3 -> N: mean of the squared distances from each point to its k
// nearest other points (exact k-d tree search; Inria's distCUDA2 is the
// approximate version with k = 3). Points with fewer than k others use all of
// them; a lone point gets 1.0. Duplicated points give 0.
std::vector<float> MeanSquaredNeighbourDistances(const std::vector<float>& xyz,
                                                 int k = 3);

// xyz N x 3 (world), rgb N x 3 in [0, 1] -> model of N Gaussians of SH degree
// `sh_degree`: DC from the colour, higher SH zero, log-scale
// log(sqrt(max(d2, 1e-7))) on all 3 axes with d2 the mean squared 3-NN
// distance, identity rotation, opacity 0.1. Throws Error on mismatched sizes
// or non-finite coordinates.
GaussianModel InitGaussiansFromPoints(const std::vector<float>& xyz,
                                      const std::vector<float>& rgb,
                                      int sh_degree);

}  // namespace watergs
