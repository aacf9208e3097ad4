// Test helper shared by the module test executables: surfaces made of flat
// Gaussians, whose geometry (and so depth) is known.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cmath>

#include "gaussian/gaussian_model.h"

namespace watergs {

// Appends to `model` (sh_degree 0) one Gaussian at `centre`, flat across the
// unit `normal`: standard deviation `sigma` in its plane, `thickness` along
// the normal, colour `rgb` in [0, 1].
inline void AppendFlatGaussian(GaussianModel* model,
                               const Eigen::Vector3d& centre,
                               const Eigen::Vector3d& normal, double sigma,
                               double thickness, float opacity_logit,
                               const std::array<float, 3>& rgb) {
  const Eigen::Quaterniond q =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal);
  model->means.insert(model->means.end(), {float(centre.x()), float(centre.y()),
                                           float(centre.z())});
  const float in_plane = float(std::log(sigma));
  model->log_scales.insert(model->log_scales.end(),
                           {in_plane, in_plane, float(std::log(thickness))});
  model->quats.insert(model->quats.end(),
                      {float(q.w()), float(q.x()), float(q.y()), float(q.z())});
  model->opacity_logits.push_back(opacity_logit);
  for (float c : rgb) model->sh_dc.push_back(RgbToShDc(c));
}

}  // namespace watergs
