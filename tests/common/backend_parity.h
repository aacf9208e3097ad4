// Shared by the CUDA-vs-CPU step parity tests (training and embedding): how
// two models that took the same optimiser steps on two backends must agree.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/gaussian_model.h"

namespace watergs::testing {

// One parameter group's arrays on both backends, Adam's largest move of one
// entry in `steps` steps (2 lr per step: Adam's first steps move an entry by
// about lr times the sign of its gradient, and a gradient that is ~0 on one
// backend may have either sign on the other), and the group name.
inline void ExpectGroupAgrees(const std::vector<float>& cpu,
                              const std::vector<float>& gpu, double max_move,
                              const std::string& name) {
  ASSERT_EQ(cpu.size(), gpu.size()) << name;
  size_t loose = 0;
  double worst = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    ASSERT_TRUE(std::isfinite(gpu[i])) << name << "[" << i << "]";
    const double d = std::abs(double(cpu[i]) - double(gpu[i]));
    worst = std::max(worst, d);
    if (d > 1e-5 * (1 + std::abs(cpu[i]))) ++loose;
  }
  EXPECT_LE(worst, max_move) << name;
  // Everything but entries with ~0 gradients agrees to float rounding.
  EXPECT_LE(loose, cpu.size() / 100)
      << name << ": " << loose << " of " << cpu.size() << " differ";
}

// Every group of two models after `steps` Adam steps with `adam` rates.
inline void ExpectModelsAgree(const GaussianModel& cpu,
                              const GaussianModel& gpu, const AdamOptions& adam,
                              double scene_extent, int steps) {
  ASSERT_EQ(cpu.size(), gpu.size());
  const double k = 2.0 * steps * 1.001;
  ExpectGroupAgrees(cpu.means, gpu.means,
                    k * adam.position_lr_init * scene_extent, "means");
  ExpectGroupAgrees(cpu.log_scales, gpu.log_scales, k * adam.scaling_lr,
                    "log_scales");
  ExpectGroupAgrees(cpu.quats, gpu.quats, k * adam.rotation_lr, "quats");
  ExpectGroupAgrees(cpu.opacity_logits, gpu.opacity_logits, k * adam.opacity_lr,
                    "opacity_logits");
  ExpectGroupAgrees(cpu.sh_dc, gpu.sh_dc, k * adam.feature_lr, "sh_dc");
  ExpectGroupAgrees(cpu.sh_rest, gpu.sh_rest, k * adam.feature_rest_lr,
                    "sh_rest");
}

}  // namespace watergs::testing
