// COLMAP camera models: names/ids/parameter counts as COLMAP 3.8 defines
// them, projection round trips for every model, and Jet derivatives of both
// directions against central finite differences in double.
#include "plugin/camera_models.h"

#include <gtest/gtest.h>

#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

constexpr int kWidth = 640, kHeight = 480;

TEST(CameraModels, IdsNamesAndParamCountsAreColmaps) {
  // From COLMAP 3.8's documentation (doc/cameras.rst, camera_models.h).
  const std::vector<std::tuple<int, std::string, int>> expected = {
      {0, "SIMPLE_PINHOLE", 3},
      {1, "PINHOLE", 4},
      {2, "SIMPLE_RADIAL", 4},
      {3, "RADIAL", 5},
      {4, "OPENCV", 8},
      {5, "OPENCV_FISHEYE", 8},
      {6, "FULL_OPENCV", 12},
      {7, "FOV", 5},
      {8, "SIMPLE_RADIAL_FISHEYE", 4},
      {9, "RADIAL_FISHEYE", 5},
      {10, "THIN_PRISM_FISHEYE", 12}};
  for (const auto& [id, name, num_params] : expected) {
    EXPECT_EQ(CameraModelIdToName(id), name);
    EXPECT_EQ(CameraModelNameToId(name), id);
    EXPECT_EQ(CameraModelNumParams(id), num_params) << name;
    EXPECT_TRUE(ExistsCameraModelWithId(id));
  }
  EXPECT_EQ(CameraModelParamsInfo(6),
            "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6");
  EXPECT_EQ(CameraModelParamsInfo(7), "fx, fy, cx, cy, omega");
  EXPECT_EQ(CameraModelNameToId("PINHOLE_X"), kInvalidCameraModelId);
  EXPECT_FALSE(ExistsCameraModelWithId(11));
  EXPECT_FALSE(ExistsCameraModelWithId(-1));
}

// Every model: pixels -> rays -> pixels over the whole image, and rays ->
// pixels -> rays.
TEST(CameraModels, RoundTripsForEveryModel) {
  for (int model_id = 0; model_id < kNumCameraModels; ++model_id) {
    const std::vector<double> params =
        testing::ExampleCameraParams(model_id, kWidth, kHeight);
    double max_pixel_error = 0, max_ray_error = 0;
    for (double y = 0.5; y < kHeight; y += 23.5) {
      for (double x = 0.5; x < kWidth; x += 31.5) {
        double u, v, x2, y2;
        CameraModelImageToWorld(model_id, params, x, y, &u, &v);
        CameraModelWorldToImage(model_id, params, u, v, &x2, &y2);
        max_pixel_error = std::max(max_pixel_error, std::hypot(x2 - x, y2 - y));
        double u2, v2;
        CameraModelImageToWorld(model_id, params, x2, y2, &u2, &v2);
        max_ray_error = std::max(max_ray_error, std::hypot(u2 - u, v2 - v));
      }
    }
    EXPECT_LT(max_pixel_error, 1e-8) << CameraModelIdToName(model_id);
    EXPECT_LT(max_ray_error, 1e-10) << CameraModelIdToName(model_id);
  }
}

// Models 2-10 with the example parameters move an off-axis ray by a
// noticeable amount relative to the plain pinhole projection.
TEST(CameraModels, DistortionActuallyDistorts) {
  for (int model_id = 2; model_id < kNumCameraModels; ++model_id) {
    const std::vector<double> params =
        testing::ExampleCameraParams(model_id, kWidth, kHeight);
    const bool single = CameraModelHasSingleFocalLength(model_id);
    const double fx = params[0], cx = params[single ? 1 : 2];
    double x, y;
    CameraModelWorldToImage(model_id, params, 0.3, -0.25, &x, &y);
    EXPECT_GT(std::abs(x - (fx * 0.3 + cx)), 0.05)
        << CameraModelIdToName(model_id);
  }
}

TEST(CameraModels, FovSeriesBranchesInvertEachOther) {
  // |omega| < 0.01 and radius^2 < 1e-4 use Taylor series; the round trip
  // must hold there too.
  for (const double omega : {0.005, 0.9}) {
    const std::vector<double> params = {500, 510, 320, 240, omega};
    for (const double r : {0.001, 0.3, 0.8}) {
      double x, y, u, v;
      CameraModelWorldToImage(7, params, r, 0.5 * r, &x, &y);
      CameraModelImageToWorld(7, params, x, y, &u, &v);
      EXPECT_NEAR(u, r, 1e-7 * (1 + r)) << omega << " " << r;
      EXPECT_NEAR(v, 0.5 * r, 1e-7 * (1 + r)) << omega << " " << r;
    }
  }
}

constexpr int kMaxInputs = 2 + 12;
using Jet = ceres::Jet<double, kMaxInputs>;

// f(inputs) -> 2 outputs, where inputs = (a, b, params...): double and Jet.
template <typename Function>
void ExpectJetMatchesFiniteDifferences(int num_params, const double* inputs,
                                       Function function,
                                       const std::string& label) {
  const int n = 2 + num_params;
  std::vector<Jet> jets(n);
  for (int i = 0; i < n; ++i) jets[i] = Jet(inputs[i], i);
  Jet out[2];
  function(jets.data(), out);
  for (int i = 0; i < n; ++i) {
    std::vector<double> plus(inputs, inputs + n), minus(inputs, inputs + n);
    const double step = 1e-6 * std::max(1.0, std::abs(inputs[i]));
    plus[i] += step;
    minus[i] -= step;
    double out_plus[2], out_minus[2];
    function(plus.data(), out_plus);
    function(minus.data(), out_minus);
    for (int k = 0; k < 2; ++k) {
      const double numeric = (out_plus[k] - out_minus[k]) / (2 * step);
      EXPECT_NEAR(out[k].v(i), numeric, 1e-5 * (1 + std::abs(numeric)))
          << label << " d out" << k << " / d input" << i;
    }
  }
}

TEST(CameraModels, JetDerivativesMatchFiniteDifferences) {
  for (int model_id = 0; model_id < kNumCameraModels; ++model_id) {
    const std::vector<double> params =
        testing::ExampleCameraParams(model_id, kWidth, kHeight);
    const int num_params = params.size();
    VisitCameraModel(model_id, [&](auto model) {
      using Model = decltype(model);
      auto world_to_image = [](const auto* in, auto* out) {
        Model::WorldToImage(in + 2, in[0], in[1], &out[0], &out[1]);
      };
      auto image_to_world = [](const auto* in, auto* out) {
        Model::ImageToWorld(in + 2, in[0], in[1], &out[0], &out[1]);
      };
      for (const auto& uv : {std::pair{0.21, -0.17}, std::pair{-0.4, 0.3}}) {
        std::vector<double> inputs = {uv.first, uv.second};
        inputs.insert(inputs.end(), params.begin(), params.end());
        ExpectJetMatchesFiniteDifferences(
            num_params, inputs.data(), world_to_image,
            std::string(Model::kModelName) + " WorldToImage");
      }
      for (const auto& xy : {std::pair{100.5, 400.5}, std::pair{600.5, 30.5}}) {
        std::vector<double> inputs = {xy.first, xy.second};
        inputs.insert(inputs.end(), params.begin(), params.end());
        ExpectJetMatchesFiniteDifferences(
            num_params, inputs.data(), image_to_world,
            std::string(Model::kModelName) + " ImageToWorld");
      }
    });
  }
}

}  // namespace
}  // namespace watergs
