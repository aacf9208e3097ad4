// Workspace: views sorted by name, render cameras from COLMAP poses and
// (undistorted, downscaled) intrinsics, image loading with size checks,
// images_<k> folders, the bounded LRU cache, the held-out split, points and
// scene extent; undistortion compared with `colmap image_undistorter`.
#include "plugin/workspace.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/undistortion.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// A smooth but textured 8-bit BGR image, different per seed.
cv::Mat TextureImage(int width, int height, int seed) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.at<cv::Vec3b>(y, x) =
          cv::Vec3b(uint8_t(127 + 120 * std::sin(0.31 * x + seed)),
                    uint8_t(127 + 120 * std::cos(0.23 * y - seed)),
                    uint8_t(127 + 120 * std::sin(0.17 * (x + y) + 0.5 * seed)));
    }
  }
  return image;
}

// Writes a synthetic model into <root>/sparse/0 and one PNG per image.
Reconstruction MakeWorkspace(const std::string& root,
                             const testing::SyntheticModelOptions& options) {
  const Reconstruction model = testing::MakeSyntheticReconstruction(options);
  WriteReconstruction(model, root + "/sparse/0", ModelFormat::kBinary);
  fs::create_directories(root + "/images");
  int seed = 0;
  for (const auto& [id, image] : model.Images()) {
    const Camera& camera = model.GetCamera(image.camera_id);
    cv::imwrite(root + "/images/" + image.name,
                TextureImage(camera.width, camera.height, seed++));
  }
  return model;
}

WorkspaceOptions OptionsFor(const std::string& root) {
  WorkspaceOptions options;
  options.workspace_path = root;
  return options;
}

// The decoded file as float RGB in [0, 1] (byte / 255.f, as every command
// reads 8-bit files), to compare LoadView with.
cv::Mat FileAsFloatRGB(const std::string& path) {
  const cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  cv::Mat rgb(bgr.rows, bgr.cols, CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      for (int c = 0; c < 3; ++c)
        rgb.at<cv::Vec3f>(y, x)[c] = bgr.at<cv::Vec3b>(y, x)[2 - c] / 255.f;
  return rgb;
}

double MaxDifference(const ImageRGB& image, const cv::Mat& rgb) {
  EXPECT_EQ(image.width, rgb.cols);
  EXPECT_EQ(image.height, rgb.rows);
  double max_difference = 0;
  for (int y = 0; y < rgb.rows; ++y) {
    for (int x = 0; x < rgb.cols; ++x) {
      for (int c = 0; c < 3; ++c) {
        max_difference = std::max(
            max_difference,
            double(std::abs(image.At(x, y)[c] - rgb.at<cv::Vec3f>(y, x)[c])));
      }
    }
  }
  return max_difference;
}

TEST(Workspace, PinholeViewsCamerasAndImages) {
  testing::TempDir dir("ws_pinhole");
  testing::SyntheticModelOptions options;
  options.model_ids = {1, 0};
  options.num_images = 10;
  const Reconstruction model = MakeWorkspace(dir.path(), options);
  const Workspace workspace = Workspace::Open(OptionsFor(dir.path()));
  ASSERT_EQ(workspace.NumViews(), 10u);
  EXPECT_FALSE(workspace.undistorted());
  for (size_t view = 0; view < workspace.NumViews(); ++view) {
    // Names frame_1000.png ... frame_1009.png, sorted.
    EXPECT_EQ(workspace.ViewName(view),
              "frame_" + std::to_string(1000 + view) + ".png");
    const Image& image = workspace.ViewImage(view);
    const Camera& camera = model.GetCamera(image.camera_id);
    const RenderCamera render = workspace.ViewCamera(view);
    EXPECT_EQ(render.width, 64);
    EXPECT_EQ(render.fx, camera.FocalLengthX());
    EXPECT_EQ(render.fy, camera.FocalLengthY());
    EXPECT_EQ(render.cx, camera.PrincipalPointX());
    EXPECT_EQ(render.cy, camera.PrincipalPointY());
    // Centre on the ring the generator placed it on.
    const double angle = 2 * M_PI * view / 10;
    const Eigen::Vector3d center(4 * std::cos(angle), 4 * std::sin(angle),
                                 0.5 * (view % 2));
    EXPECT_LT((render.Center() - center).norm(), 1e-6);
    const ImageRGB loaded = workspace.LoadView(view);
    EXPECT_EQ(MaxDifference(
                  loaded, FileAsFloatRGB(dir.path() + "/images/" + image.name)),
              0.0);
  }
  double max_distance = 0;
  Eigen::Vector3d mean(0, 0, 0.25);
  for (size_t view = 0; view < 10; ++view) {
    const double angle = 2 * M_PI * view / 10;
    max_distance = std::max(
        max_distance, (Eigen::Vector3d(4 * std::cos(angle), 4 * std::sin(angle),
                                       0.5 * (view % 2)) -
                       mean)
                          .norm());
  }
  EXPECT_NEAR(workspace.SceneExtent(), 1.1 * max_distance, 1e-6);
}

TEST(Workspace, InputPathAloneFindsImagesBesideSparse) {
  testing::TempDir dir("ws_input_only");
  MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  WorkspaceOptions options;
  options.input_path = dir / "sparse/0";
  const Workspace workspace = Workspace::Open(options);
  EXPECT_EQ(workspace.options().image_path, dir / "images");
  EXPECT_EQ(workspace.LoadView(0).width, 64);
}

TEST(Workspace, HeldOutSplitEveryEighthView) {
  testing::TempDir dir("ws_split");
  testing::SyntheticModelOptions options;
  options.num_images = 17;
  MakeWorkspace(dir.path(), options);
  const Workspace workspace = Workspace::Open(OptionsFor(dir.path()));
  EXPECT_EQ(workspace.TestViews(true), (std::vector<size_t>{0, 8, 16}));
  EXPECT_EQ(workspace.TrainViews(true).size(), 14u);
  EXPECT_EQ(workspace.TrainViews(true).front(), 1u);
  EXPECT_TRUE(workspace.TestViews(false).empty());
  EXPECT_EQ(workspace.TrainViews(false).size(), 17u);
}

TEST(Workspace, PointCloudSortedByIdWithUnitColors) {
  testing::TempDir dir("ws_points");
  const Reconstruction model =
      MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  const Workspace workspace = Workspace::Open(OptionsFor(dir.path()));
  std::vector<float> xyz, rgb;
  workspace.PointCloud(&xyz, &rgb);
  ASSERT_EQ(xyz.size(), 3 * model.NumPoints3D());
  ASSERT_EQ(rgb.size(), xyz.size());
  point3D_t smallest = kInvalidPoint3DId;
  for (const auto& [id, point] : model.Points3D()) {
    smallest = std::min(smallest, id);
  }
  const Point3D& first = model.GetPoint3D(smallest);
  EXPECT_FLOAT_EQ(xyz[0], first.xyz.x());
  EXPECT_FLOAT_EQ(rgb[2], first.rgb(2) / 255.f);
  for (const float value : rgb) {
    EXPECT_GE(value, 0.f);
    EXPECT_LE(value, 1.f);
  }
}

TEST(Workspace, DownscaleResizesWithInterArea) {
  testing::TempDir dir("ws_down");
  MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  WorkspaceOptions options = OptionsFor(dir.path());
  options.downscale = 4;
  const Workspace workspace = Workspace::Open(options);
  const RenderCamera camera = workspace.ViewCamera(0);
  EXPECT_EQ(camera.width, 16);
  EXPECT_EQ(camera.height, 12);
  const Camera& colmap_camera =
      workspace.reconstruction().GetCamera(workspace.ViewImage(0).camera_id);
  EXPECT_DOUBLE_EQ(camera.fx, colmap_camera.FocalLengthX() / 4);
  EXPECT_DOUBLE_EQ(camera.cy, colmap_camera.PrincipalPointY() / 4);
  cv::Mat expected;
  cv::resize(FileAsFloatRGB(dir.path() + "/images/" + workspace.ViewName(0)),
             expected, cv::Size(16, 12), 0, 0, cv::INTER_AREA);
  EXPECT_LT(MaxDifference(workspace.LoadView(0), expected), 1e-6);
}

TEST(Workspace, DownscaleUsesImagesKFolderWhenPresent) {
  testing::TempDir dir("ws_images2");
  MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  WorkspaceOptions options = OptionsFor(dir.path());
  options.downscale = 2;
  fs::create_directories(dir / "images_2");
  const Workspace workspace = Workspace::Open(options);
  // A flat grey the resized full image could never be.
  cv::imwrite(dir / ("images_2/" + workspace.ViewName(1)),
              cv::Mat(24, 32, CV_8UC3, cv::Scalar(51, 51, 51)));
  const ImageRGB image = workspace.LoadView(1);
  EXPECT_EQ(image.width, 32);
  EXPECT_FLOAT_EQ(image.At(5, 7)[1], 51 / 255.f);
  // A wrong-size file there is refused, naming it.
  cv::imwrite(dir / ("images_2/" + workspace.ViewName(2)),
              cv::Mat(10, 10, CV_8UC3));
  try {
    workspace.LoadView(2);
    ADD_FAILURE() << "size mismatch not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("images_2/" + workspace.ViewName(2)),
              std::string::npos);
  }
}

TEST(Workspace, CacheIsBoundedLeastRecentlyUsed) {
  testing::TempDir dir("ws_cache");
  MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  WorkspaceOptions options = OptionsFor(dir.path());
  const size_t image_bytes = 64 * 48 * 3 * sizeof(float);
  options.image_cache_bytes = 2 * image_bytes;  // two views fit
  const Workspace workspace = Workspace::Open(options);
  const ImageRGB view0 = workspace.LoadView(0);
  workspace.LoadView(1);
  workspace.LoadView(0);  // 0 is now the most recent, 1 the eviction victim
  workspace.LoadView(2);
  // Overwrite the files: cached views keep their old pixels, evicted ones
  // are decoded again.
  for (size_t view : {0, 1}) {
    cv::imwrite(dir / ("images/" + workspace.ViewName(view)),
                cv::Mat(48, 64, CV_8UC3, cv::Scalar(0, 0, 0)));
  }
  EXPECT_EQ(workspace.LoadView(0).data, view0.data);
  EXPECT_EQ(workspace.LoadView(1).At(3, 3)[0], 0.f);
}

TEST(Workspace, MissingImageAndSizeMismatchNameTheFile) {
  testing::TempDir dir("ws_bad");
  const Reconstruction model =
      MakeWorkspace(dir.path(), testing::SyntheticModelOptions{});
  const std::string name = model.GetImage(model.RegImageIds()[0]).name;
  const std::string path = dir / ("images/" + name);
  cv::imwrite(path, cv::Mat(40, 64, CV_8UC3));
  try {
    Workspace::Open(OptionsFor(dir.path()));
    ADD_FAILURE() << "size mismatch not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": is 64x40 but its camera"),
              std::string::npos)
        << e.what();
  }
  // JPEG headers are read as well.
  fs::remove(path);
  try {
    Workspace::Open(OptionsFor(dir.path()));
    ADD_FAILURE() << "missing image not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": missing"), std::string::npos)
        << e.what();
  }
  const testing::CommandResult cli =
      testing::RunCommand(testing::WatergsBin() + " model_info --sparse_path " +
                          dir.path() + "/nowhere");
  EXPECT_NE(cli.exit_code, 0);
}

// Photos resized at their camera's aspect ratio (LLFF copies at 800x600 of
// a 4032x3024 camera) scale its intrinsics, with one notice; another aspect
// ratio stays an error naming the file.
TEST(Workspace, PhotosSmallerThanTheirCameraScaleItsIntrinsics) {
  testing::TempDir dir("ws_scaled");
  testing::SyntheticModelOptions options;
  options.model_ids = {1, 2};
  options.width = 64;
  options.height = 48;
  const Reconstruction model = MakeWorkspace(dir.path(), options);
  const Workspace full = Workspace::Open(OptionsFor(dir.path()));
  EXPECT_TRUE(full.notices().empty());
  int seed = 0;
  for (const auto& [id, image] : model.Images()) {
    cv::imwrite(dir / ("images/" + image.name), TextureImage(32, 24, seed++));
  }
  const Workspace half = Workspace::Open(OptionsFor(dir.path()));
  ASSERT_EQ(half.notices().size(), 2u);
  EXPECT_NE(half.notices()[0].find("are 32x24, the camera 64x48"),
            std::string::npos)
      << half.notices()[0];
  // Pinhole views exactly half; undistorted ones (whose pinhole camera is
  // fitted to the distorted image's bounds) within a pixel.
  for (size_t view = 0; view < half.NumViews(); ++view) {
    const RenderCamera a = full.ViewCamera(view), b = half.ViewCamera(view);
    const bool pinhole =
        model.GetCamera(half.ViewImage(view).camera_id).model_id == 1;
    const double pixel_tolerance = pinhole ? 1e-9 : 1.0;
    EXPECT_NEAR(b.width, 0.5 * a.width, pinhole ? 0 : 1);
    EXPECT_NEAR(b.height, 0.5 * a.height, pinhole ? 0 : 1);
    EXPECT_NEAR(b.fx, 0.5 * a.fx, pixel_tolerance);
    EXPECT_NEAR(b.fy, 0.5 * a.fy, pixel_tolerance);
    EXPECT_NEAR(b.cx, 0.5 * a.cx, pixel_tolerance);
    EXPECT_NEAR(b.cy, 0.5 * a.cy, pixel_tolerance);
    EXPECT_EQ(half.LoadView(view).width, b.width);
  }
  // The pinhole camera's photo is read as is.
  size_t pinhole_view = half.NumViews();
  for (size_t view = 0; view < half.NumViews(); ++view) {
    const camera_t camera = half.ViewImage(view).camera_id;
    if (model.GetCamera(camera).model_id == 1) pinhole_view = view;
  }
  ASSERT_LT(pinhole_view, half.NumViews());
  EXPECT_EQ(MaxDifference(half.LoadView(pinhole_view),
                          FileAsFloatRGB(
                              dir / ("images/" + half.ViewName(pinhole_view)))),
            0.0);
  // Another aspect ratio: the first photo's error, no scaling.
  for (const auto& [id, image] : model.Images()) {
    cv::imwrite(dir / ("images/" + image.name), TextureImage(32, 20, 1));
  }
  try {
    Workspace::Open(OptionsFor(dir.path()));
    ADD_FAILURE() << "another aspect ratio not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(": is 32x20 but its camera"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("another aspect ratio"),
              std::string::npos)
        << e.what();
  }
}

TEST(Workspace, JpegSizeCheckedFromHeader) {
  testing::TempDir dir("ws_jpeg");
  testing::SyntheticModelOptions options;
  Reconstruction model = testing::MakeSyntheticReconstruction(options);
  WriteReconstruction(model, dir / "sparse", ModelFormat::kText);
  fs::create_directories(dir / "images");
  for (const auto& [id, image] : model.Images()) {
    cv::imwrite(dir / ("images/" + image.name), TextureImage(64, 48, 1));
  }
  // A JPEG (by content) under the first name, 1 pixel too narrow.
  const std::string name = model.GetImage(model.RegImageIds()[0]).name;
  std::vector<uint8_t> jpeg;
  cv::imencode(".jpg", TextureImage(63, 48, 2), jpeg);
  AtomicWriteFile(dir / ("images/" + name),
                  std::string(jpeg.begin(), jpeg.end()));
  try {
    Workspace::Open(OptionsFor(dir.path()));
    ADD_FAILURE() << "JPEG size mismatch not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is 63x48"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace watergs
