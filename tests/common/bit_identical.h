// Test helper shared by the module test executables: two runs that must end
// in the same state (resume, thread counts, a run without layers) compared
// byte for byte over every parameter group and every optimiser moment, so
// that a difference in any one of them shows and names itself.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/gaussian_model.h"

namespace watergs::testing {

// a and b hold the same bytes; on a difference, reports the first index
// (EXPECT_EQ on vectors would print every element).
template <typename T>
void ExpectSameBytes(const std::vector<T>& a, const std::vector<T>& b,
                     const std::string& name) {
  ASSERT_EQ(a.size(), b.size()) << name;
  if (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0)
    return;
  size_t i = 0;
  while (std::memcmp(&a[i], &b[i], sizeof(T)) == 0) ++i;
  ADD_FAILURE() << name << " differs first at [" << i << "] of " << a.size()
                << ": " << +a[i] << " vs " << +b[i];
}

// Every parameter group of two models.
inline void ExpectBitIdenticalModels(const GaussianModel& a,
                                     const GaussianModel& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.sh_degree, b.sh_degree);
  for (int g = 0; g < kNumParamGroups; ++g) {
    const ParamGroup group = static_cast<ParamGroup>(g);
    ExpectSameBytes(GroupParams(a, group), GroupParams(b, group),
                    GroupName(group));
  }
}

// Every moment array of one group's optimiser state (float, 8-bit and
// bfloat16 forms; the unused ones are empty on both sides) and its step.
inline void ExpectSameAdamGroup(const AdamGroupState& a,
                                const AdamGroupState& b,
                                const std::string& group) {
  ExpectSameBytes(a.exp_avg, b.exp_avg, group + " exp_avg");
  ExpectSameBytes(a.exp_avg_sq, b.exp_avg_sq, group + " exp_avg_sq");
  ExpectSameBytes(a.exp_avg_q, b.exp_avg_q, group + " exp_avg_q");
  ExpectSameBytes(a.exp_avg_sq_shared, b.exp_avg_sq_shared,
                  group + " exp_avg_sq_shared");
  ExpectSameBytes(a.exp_avg_h, b.exp_avg_h, group + " exp_avg_h");
  ExpectSameBytes(a.exp_avg_sq_h, b.exp_avg_sq_h, group + " exp_avg_sq_h");
  EXPECT_EQ(a.step, b.step) << group;
}

}  // namespace watergs::testing
