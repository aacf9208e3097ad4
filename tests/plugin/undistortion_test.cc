// Undistortion against the real `colmap image_undistorter` (defaults): same
// pinhole intrinsics and size for every distorted model, same pixels up to
// interpolation rounding; pinhole cameras pass through untouched.
#include "plugin/undistortion.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "plugin/reconstruction_io.h"
#include "plugin/workspace.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

cv::Mat Texture(int width, int height, int seed) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.at<cv::Vec3b>(y, x) =
          cv::Vec3b(uint8_t(127 + 120 * std::sin(0.31 * x + seed)),
                    uint8_t(127 + 120 * std::cos(0.23 * y - seed)),
                    uint8_t(127 + 120 * std::sin(0.17 * (x + y))));
    }
  }
  return image;
}

TEST(Undistortion, PinholeCamerasPassThrough) {
  const Camera simple{3, 0, 64, 48, {50, 32, 24}};
  const Camera pinhole = UndistortCamera(simple);
  EXPECT_EQ(pinhole.model_id, 1);
  EXPECT_EQ(pinhole.width, 64u);
  EXPECT_EQ(pinhole.params, (std::vector<double>{50, 50, 32, 24}));
  const WarpMap map = ComputeWarpMap(simple, pinhole);
  for (int row : {0, 47}) {
    for (int col : {0, 31, 63}) {
      EXPECT_NEAR(map.map_x.at<float>(row, col), col, 1e-4);
      EXPECT_NEAR(map.map_y.at<float>(row, col), row, 1e-4);
    }
  }
}

TEST(Undistortion, SizeFollowsDistortionAndLeavesNoBlankPixels) {
  // Barrel distortion (k < 0) squeezes a wider field into the frame, so the
  // blank-free pinhole image is larger at the same focal length; pincushion
  // (k > 0) the opposite.
  for (const double k : {-0.2, 0.2}) {
    const Camera camera{1, 2, 640, 480, {500, 320, 240, k}};
    const Camera pinhole = UndistortCamera(camera);
    EXPECT_EQ(pinhole.params[0], 500);
    EXPECT_EQ(pinhole.width > 640u, k < 0) << k << " " << pinhole.width;
    EXPECT_EQ(pinhole.height > 480u, k < 0) << k << " " << pinhole.height;
    // Every pinhole pixel centre maps inside the distorted image.
    const WarpMap map = ComputeWarpMap(camera, pinhole);
    double min_x, max_x, min_y, max_y;
    cv::minMaxLoc(map.map_x, &min_x, &max_x);
    cv::minMaxLoc(map.map_y, &min_y, &max_y);
    EXPECT_GE(min_x, -0.5 - 1e-3) << k;
    EXPECT_LE(max_x, 639.5 + 1e-3) << k;
    EXPECT_GE(min_y, -0.5 - 1e-3) << k;
    EXPECT_LE(max_y, 479.5 + 1e-3) << k;
  }
}

class ColmapUndistorter : public ::testing::Test {
 protected:
  // A workspace with one camera per distorted model (2-10) and one image
  // each, plus colmap image_undistorter's output for it.
  void SetUp() override {
    testing::SyntheticModelOptions options;
    options.model_ids = {2, 3, 4, 5, 6, 7, 8, 9, 10};
    options.num_images = 9;
    options.width = 96;
    options.height = 72;
    model_ = testing::MakeSyntheticReconstruction(options);
    WriteReconstruction(model_, dir_ / "sparse/0", ModelFormat::kBinary);
    fs::create_directories(dir_ / "images");
    int seed = 0;
    for (const auto& [id, image] : model_.Images()) {
      cv::imwrite(dir_ / ("images/" + image.name), Texture(96, 72, seed++));
    }
    const testing::CommandResult result = testing::RunCommand(
        "QT_QPA_PLATFORM=offscreen colmap image_undistorter --image_path " +
        dir_ / "images" + " --input_path " + dir_ / "sparse/0" +
        " --output_path " + dir_ / "colmap_out" + " --output_type COLMAP");
    ASSERT_EQ(result.exit_code, 0) << result.output;
    colmap_model_ = ReadReconstruction(dir_ / "colmap_out/sparse");
  }

  testing::TempDir dir_{"undistorter"};
  Reconstruction model_, colmap_model_;
};

TEST_F(ColmapUndistorter, SameIntrinsicsAsColmapForEveryDistortedModel) {
  ASSERT_EQ(colmap_model_.NumCameras(), 9u);
  for (const auto& [id, camera] : model_.Cameras()) {
    const Camera ours = UndistortCamera(camera);
    const Camera& theirs = colmap_model_.GetCamera(id);
    EXPECT_EQ(theirs.ModelName(), "PINHOLE");
    EXPECT_EQ(ours.width, theirs.width) << camera.ModelName();
    EXPECT_EQ(ours.height, theirs.height) << camera.ModelName();
    for (int k = 0; k < 4; ++k) {
      EXPECT_NEAR(ours.params[k], theirs.params[k], 1e-9 * theirs.params[k])
          << camera.ModelName() << " param " << k;
    }
  }
}

TEST_F(ColmapUndistorter, SamePixelsAsColmap) {
  WorkspaceOptions options;
  options.workspace_path = dir_.path();
  const Workspace workspace = Workspace::Open(options);
  EXPECT_TRUE(workspace.undistorted());
  for (size_t view = 0; view < workspace.NumViews(); ++view) {
    const ImageRGB ours = workspace.LoadView(view);
    cv::Mat theirs =
        cv::imread(dir_ / ("colmap_out/images/" + workspace.ViewName(view)));
    ASSERT_EQ(ours.width, theirs.cols);
    ASSERT_EQ(ours.height, theirs.rows);
    double sum = 0;
    int count = 0;
    for (int y = 2; y < theirs.rows - 2; ++y) {
      for (int x = 2; x < theirs.cols - 2; ++x) {
        const cv::Vec3b bgr = theirs.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) {
          sum += std::abs(ours.At(x, y)[c] - bgr[2 - c] / 255.0);
          ++count;
        }
      }
    }
    // Half a pixel of misalignment would give ~0.07 on this texture.
    EXPECT_LT(sum / count, 0.01) << workspace.ViewName(view);
  }
}

TEST_F(ColmapUndistorter, DownscaleAppliesAfterUndistortion) {
  // At downscale k a view is the undistorted image cropped (centred, whole
  // pixels) to a multiple of k and reduced exactly k-fold: an odd size
  // rounded instead would resample every photo at a non-integer ratio and
  // blur it (docs/reconstruct.md).
  WorkspaceOptions options;
  options.workspace_path = dir_.path();
  const Workspace full = Workspace::Open(options);
  options.downscale = 2;
  const Workspace half = Workspace::Open(options);
  int odd = 0;
  for (size_t view = 0; view < full.NumViews(); ++view) {
    const RenderCamera big = full.ViewCamera(view);
    const RenderCamera small = half.ViewCamera(view);
    odd += big.width % 2 + big.height % 2;
    EXPECT_EQ(small.width, big.width / 2);
    EXPECT_EQ(small.height, big.height / 2);
    const int left = (big.width - 2 * small.width) / 2;
    const int top = (big.height - 2 * small.height) / 2;
    EXPECT_NEAR(small.fx, big.fx / 2, 1e-12);
    EXPECT_NEAR(small.fy, big.fy / 2, 1e-12);
    EXPECT_NEAR(small.cx, (big.cx - left) / 2, 1e-12);
    EXPECT_NEAR(small.cy, (big.cy - top) / 2, 1e-12);
    const ImageRGB full_image = full.LoadView(view);
    cv::Mat full_mat(full_image.height, full_image.width, CV_32FC3,
                     const_cast<float*>(full_image.data.data()));
    cv::Mat expected;
    cv::resize(full_mat(cv::Rect(left, top, 2 * small.width, 2 * small.height)),
               expected, cv::Size(small.width, small.height), 0, 0,
               cv::INTER_AREA);
    const ImageRGB half_image = half.LoadView(view);
    ASSERT_EQ(half_image.width, expected.cols);
    ASSERT_EQ(half_image.height, expected.rows);
    for (int y = 0; y < expected.rows; y += 5) {
      for (int x = 0; x < expected.cols; x += 5) {
        EXPECT_NEAR(half_image.At(x, y)[1], expected.at<cv::Vec3f>(y, x)[1],
                    1e-5);
      }
    }
  }
  EXPECT_GT(odd, 0) << "no undistorted size to crop: the test tests nothing";
}

TEST_F(ColmapUndistorter, DistortedImagesFromImagesKFolder) {
  // images_2 holding the INTER_AREA-halved originals must give nearly the
  // views computed from the full images.
  fs::create_directories(dir_ / "images_2");
  for (const auto& [id, image] : model_.Images()) {
    cv::Mat half;
    cv::resize(cv::imread(dir_ / ("images/" + image.name)), half,
               cv::Size(48, 36), 0, 0, cv::INTER_AREA);
    cv::imwrite(dir_ / ("images_2/" + image.name), half);
  }
  WorkspaceOptions options;
  options.workspace_path = dir_.path();
  options.downscale = 2;
  const Workspace workspace = Workspace::Open(options);
  fs::rename(dir_ / "images_2", dir_ / "moved_away");
  const Workspace reference = Workspace::Open(options);
  fs::rename(dir_ / "moved_away", dir_ / "images_2");
  for (size_t view = 0; view < workspace.NumViews(); ++view) {
    const ImageRGB ours = workspace.LoadView(view);
    const ImageRGB expected = reference.LoadView(view);
    ASSERT_EQ(ours.width, expected.width);
    ASSERT_EQ(ours.height, expected.height);
    double sum = 0;
    int count = 0;
    for (int y = 2; y < ours.height - 2; ++y) {
      for (int x = 2; x < ours.width - 2; ++x) {
        for (int c = 0; c < 3; ++c) {
          sum += std::abs(ours.At(x, y)[c] - expected.At(x, y)[c]);
          ++count;
        }
      }
    }
    EXPECT_LT(sum / count, 0.03) << workspace.ViewName(view);
  }
  // And the images_2 file is what is read: a flat grey one stays grey.
  const std::string name = workspace.ViewName(3);
  cv::imwrite(dir_ / ("images_2/" + name),
              cv::Mat(36, 48, CV_8UC3, cv::Scalar(51, 51, 51)));
  const ImageRGB grey = Workspace::Open(options).LoadView(3);
  EXPECT_NEAR(grey.At(grey.width / 2, grey.height / 2)[0], 0.2f, 1e-6);
}

TEST_F(ColmapUndistorter, WorkspaceCanDelegateToColmap) {
  WorkspaceOptions options;
  options.workspace_path = dir_.path();
  options.use_colmap_undistorter = true;
  options.undistorted_path = dir_ / "delegated";
  const Workspace workspace = Workspace::Open(options);
  EXPECT_TRUE(fs::exists(dir_ / "delegated/sparse/cameras.bin"));
  for (size_t view = 0; view < workspace.NumViews(); ++view) {
    const RenderCamera camera = workspace.ViewCamera(view);
    const Camera& theirs =
        colmap_model_.GetCamera(workspace.ViewImage(view).camera_id);
    EXPECT_EQ(uint64_t(camera.width), theirs.width);
    EXPECT_NEAR(camera.cx, theirs.params[2], 1e-12);
    const ImageRGB image = workspace.LoadView(view);
    const cv::Mat theirs_image =
        cv::imread(dir_ / ("colmap_out/images/" + workspace.ViewName(view)));
    EXPECT_FLOAT_EQ(image.At(10, 10)[0],
                    theirs_image.at<cv::Vec3b>(10, 10)[2] / 255.f);
  }
}

}  // namespace
}  // namespace watergs
