// transforms.json scenes as COLMAP workspaces: the OpenGL camera convention
// checked by projecting points whose image position is known by construction
// (in front, right of and above a camera), alpha composited exactly, the
// scene's test split held out by the Workspace, nerfstudio's intrinsics and
// distortion carried into COLMAP camera models, the random points around
// where the cameras look, a train --split train run on an imported scene, and
// bad files refused in one line naming the file without a half-written output.
#include "plugin/transforms_import.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "gaussian/util/error.h"
#include "plugin/workspace.h"
#include "tests/common/refusal.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::Refusal;
using testing::TempDir;

// OpenGL camera-to-world of a camera at `centre` looking at `target`, world
// up +z (Blender's): columns right, up, backwards, centre.
Eigen::Matrix4d GlLookAt(const Eigen::Vector3d& centre,
                         const Eigen::Vector3d& target) {
  const Eigen::Vector3d back = (centre - target).normalized();
  const Eigen::Vector3d right =
      Eigen::Vector3d::UnitZ().cross(back).normalized();
  const Eigen::Vector3d up = back.cross(right);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 1>(0, 0) = right;
  m.block<3, 1>(0, 1) = up;
  m.block<3, 1>(0, 2) = back;
  m.block<3, 1>(0, 3) = centre;
  return m;
}

json MatrixJson(const Eigen::Matrix4d& m) {
  json rows = json::array();
  for (int r = 0; r < 4; ++r) {
    rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  }
  return rows;
}

// A w x h BGRA PNG of one colour and alpha.
void WriteRgba(const std::string& path, int w, int h, cv::Vec4b bgra) {
  fs::create_directories(fs::path(path).parent_path());
  ASSERT_TRUE(cv::imwrite(path, cv::Mat(h, w, CV_8UC4, cv::Scalar(bgra))));
}

void WriteJson(const std::string& path, const json& value) {
  std::ofstream(path) << value.dump(1);
}

// NeRF-synthetic's layout: transforms_{train,test}.json with extension-less
// "./split/r_i" paths, camera_angle_x, RGBA PNGs of 16x12; `train` and
// `test` cameras on a ring of radius 4 around the origin.
std::string WriteBlenderScene(const TempDir& dir, int train, int test,
                              double angle_x = 0.69) {
  const std::string root = dir / "scene";
  for (const std::string split : {"train", "test"}) {
    json file = {{"camera_angle_x", angle_x}, {"frames", json::array()}};
    const int count = split == "train" ? train : test;
    if (count == 0) continue;
    for (int i = 0; i < count; ++i) {
      const double a = 2 * M_PI * (i + (split == "test" ? 0.5 : 0)) / count;
      const Eigen::Vector3d centre(4 * std::cos(a), 4 * std::sin(a), 1);
      file["frames"].push_back(
          {{"file_path", "./" + split + "/r_" + std::to_string(i)},
           {"transform_matrix", MatrixJson(GlLookAt(centre, {0, 0, 0}))}});
      WriteRgba(root + "/" + split + "/r_" + std::to_string(i) + ".png", 16, 12,
                cv::Vec4b(50, 100, 200, 255));
    }
    WriteJson(root + "/transforms_" + split + ".json", file);
  }
  return root;
}

Eigen::Vector3d InCamera(const RenderCamera& camera, const Eigen::Vector3d& x) {
  return camera.R * x + camera.t;
}

TEST(TransformsImport, OpenGlCamerasProjectWhereTheyLook) {
  TempDir dir("transforms_gl");
  const std::string scene = WriteBlenderScene(dir, 8, 0, M_PI / 2);
  TransformsImportOptions options;
  options.transforms_path = scene;
  options.output_path = dir / "ws";
  options.num_points = 10;
  ImportTransforms(options);
  WorkspaceOptions wo;
  wo.workspace_path = options.output_path;
  const Workspace workspace = Workspace::Open(wo);
  ASSERT_EQ(workspace.NumViews(), 8u);
  for (size_t v = 0; v < workspace.NumViews(); ++v) {
    const RenderCamera camera = workspace.ViewCamera(v);
    EXPECT_NEAR(camera.fx, 8.0, 1e-9);  // w / 2 / tan(pi / 4)
    EXPECT_NEAR(camera.cx, 8.0, 1e-12);
    EXPECT_NEAR(camera.cy, 6.0, 1e-12);
    // The origin, looked at, lies ahead on the axis at the camera's distance.
    const Eigen::Vector3d origin = InCamera(camera, Eigen::Vector3d::Zero());
    EXPECT_NEAR(origin.x(), 0, 1e-9);
    EXPECT_NEAR(origin.y(), 0, 1e-9);
    EXPECT_NEAR(origin.z(), std::sqrt(17.0), 1e-9);
    // World up appears above the centre (smaller row), in COLMAP's y-down.
    EXPECT_LT(InCamera(camera, Eigen::Vector3d(0, 0, 0.3)).y(), -0.1);
  }
  // The first camera sits at +x, looking towards -x: +y is on its right.
  const RenderCamera first = workspace.ViewCamera(0);
  EXPECT_GT(InCamera(first, Eigen::Vector3d(0, 0.3, 0)).x(), 0.1);
  EXPECT_NEAR(workspace.ViewImage(0).ProjectionCenter().x(), 4, 1e-9);
}

TEST(TransformsImport, AlphaIsCompositedOnTheBackground) {
  TempDir dir("transforms_alpha");
  const std::string root = dir / "scene";
  WriteRgba(root + "/a.png", 4, 4, cv::Vec4b(50, 100, 200, 128));
  const cv::Mat jpeg(4, 4, CV_8UC3, cv::Scalar(10, 20, 30));
  ASSERT_TRUE(cv::imwrite(root + "/b.jpg", jpeg));
  json file = {{"fl_x", 3.0}, {"frames", json::array()}};
  for (const char* name : {"a.png", "b.jpg"}) {
    file["frames"].push_back(
        {{"file_path", name},
         {"transform_matrix", MatrixJson(GlLookAt({4, 0, 0}, {0, 0, 0}))}});
  }
  WriteJson(root + "/transforms.json", file);
  TransformsImportOptions options;
  options.transforms_path = root + "/transforms.json";
  options.output_path = dir / "ws";
  options.background = {1.f, 0.5f, 0.f};
  options.num_points = 5;
  const TransformsImportSummary summary = ImportTransforms(options);
  EXPECT_EQ(summary.composited, 1u);
  EXPECT_EQ(summary.test_views, 0u);
  const cv::Mat out = cv::imread(options.output_path + "/images/a.png");
  ASSERT_EQ(out.type(), CV_8UC3);
  const double a = 128 / 255.0;
  const cv::Vec3b pixel = out.at<cv::Vec3b>(2, 2);  // BGR
  EXPECT_EQ(pixel[2], std::lround(255 * (200 / 255.0 * a + 1.0 * (1 - a))));
  EXPECT_EQ(pixel[1], std::lround(255 * (100 / 255.0 * a + 0.5 * (1 - a))));
  EXPECT_EQ(pixel[0], std::lround(255 * (50 / 255.0 * a)));
  // An image without alpha is copied as it is.
  std::ifstream in_a(root + "/b.jpg", std::ios::binary);
  std::ifstream in_b(options.output_path + "/images/b.jpg", std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in_a), {}),
            std::string(std::istreambuf_iterator<char>(in_b), {}));
  // Without a test split, the Workspace holds out every 8th view as before.
  WorkspaceOptions wo;
  wo.workspace_path = options.output_path;
  EXPECT_EQ(Workspace::Open(wo).TestViews(true), std::vector<size_t>{0});
}

TEST(TransformsImport, TheScenesTestSplitIsHeldOut) {
  TempDir dir("transforms_split");
  TransformsImportOptions options;
  options.transforms_path = WriteBlenderScene(dir, 5, 6);
  options.output_path = dir / "ws";
  options.num_points = 10;
  options.test_stride = 2;
  const TransformsImportSummary summary = ImportTransforms(options);
  EXPECT_EQ(summary.train_views, 5u);
  EXPECT_EQ(summary.test_views, 3u);  // frames 0, 2, 4
  WorkspaceOptions wo;
  wo.workspace_path = options.output_path;
  const Workspace workspace = Workspace::Open(wo);
  ASSERT_EQ(workspace.NumViews(), 8u);
  std::vector<std::string> test, train;
  for (size_t v : workspace.TestViews(true))
    test.push_back(workspace.ViewName(v));
  for (size_t v : workspace.TrainViews(true)) {
    train.push_back(workspace.ViewName(v));
  }
  EXPECT_EQ(test, (std::vector<std::string>{"test/r_0.png", "test/r_2.png",
                                            "test/r_4.png"}));
  ASSERT_EQ(train.size(), 5u);
  for (const std::string& name : train) EXPECT_EQ(name.rfind("train/", 0), 0u);
  EXPECT_EQ(workspace.TrainViews(false).size(), 8u);
  // A split file naming an image the model lacks is refused in one line.
  std::ofstream(options.output_path + "/test_views.txt", std::ios::app)
      << "test/r_9.png\n";
  const std::string message = Refusal(options.output_path + "/test_views.txt",
                                      [&] { Workspace::Open(wo); });
  EXPECT_NE(message.find("r_9.png"), std::string::npos) << message;
}

TEST(TransformsImport, NerfstudioIntrinsicsBecomeColmapCameras) {
  TempDir dir("transforms_ns");
  const std::string root = dir / "scene";
  WriteRgba(root + "/images/f1.png", 20, 10, cv::Vec4b(1, 2, 3, 255));
  json file = {{"fl_x", 30.0},
               {"fl_y", 31.0},
               {"cx", 9.5},
               {"cy", 5.25},
               {"w", 20},
               {"h", 10},
               {"k1", 0.01},
               {"k2", -0.002},
               {"p1", 0.001},
               {"p2", 0.0005},
               {"frames", json::array()}};
  const json matrix = MatrixJson(GlLookAt({3, 0, 0}, {0, 0, 0}));
  file["frames"].push_back(
      {{"file_path", "images/f1.png"}, {"transform_matrix", matrix}});
  file["frames"].push_back({{"file_path", "images/f1.png"},
                            {"transform_matrix", matrix},
                            {"fl_x", 40.0}});
  WriteJson(root + "/transforms.json", file);
  const std::vector<TransformsFrame> frames = ReadTransforms(root);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].camera.model_id, OpenCVCameraModel::kModelId);
  EXPECT_EQ(
      frames[0].camera.params,
      (std::vector<double>{30, 31, 9.5, 5.25, 0.01, -0.002, 0.001, 0.0005}));
  EXPECT_EQ(frames[1].camera.params[0], 40.0);  // the frame's own key wins
  EXPECT_EQ(frames[0].workspace_name, "images/f1.png");

  file["camera_model"] = "OPENCV_FISHEYE";
  WriteJson(root + "/transforms.json", file);
  EXPECT_EQ(ReadTransforms(root)[0].camera.model_id,
            OpenCVFisheyeCameraModel::kModelId);
  file.erase("k1"), file.erase("k2"), file.erase("p1"), file.erase("p2");
  file["camera_model"] = "OPENCV";
  WriteJson(root + "/transforms.json", file);
  EXPECT_EQ(ReadTransforms(root)[0].camera.model_id,
            PinholeCameraModel::kModelId);
  file["camera_model"] = "EQUIRECTANGULAR";
  WriteJson(root + "/transforms.json", file);
  const std::string message = Refusal(root + "/transforms.json: frame 0",
                                      [&] { ReadTransforms(root); });
  EXPECT_NE(message.find("EQUIRECTANGULAR"), std::string::npos);
}

TEST(TransformsImport, RandomPointsSurroundWhereTheCamerasLook) {
  const Eigen::Vector3d target(1, 2, 3);
  std::vector<Image> images;
  for (int i = 0; i < 7; ++i) {
    const double a = 2 * M_PI * i / 7;
    images.push_back(ImageFromCameraToWorld(GlLookAt(
        target + Eigen::Vector3d(5 * std::cos(a), 5 * std::sin(a), 0.5 * i),
        target)));
  }
  EXPECT_LT((LookAtCentre(images) - target).norm(), 1e-9);
  // Parallel axes (a forward-facing capture): the mean centre.
  std::vector<Image> parallel;
  for (int i = 0; i < 3; ++i) {
    parallel.push_back(ImageFromCameraToWorld(
        GlLookAt(Eigen::Vector3d(i, 0, 0), Eigen::Vector3d(i, 5, 0))));
  }
  EXPECT_LT((LookAtCentre(parallel) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-9);

  TempDir dir("transforms_points");
  TransformsImportOptions options;
  options.transforms_path = WriteBlenderScene(dir, 6, 0);
  options.output_path = dir / "ws";
  options.num_points = 400;
  const TransformsImportSummary summary = ImportTransforms(options);
  EXPECT_EQ(summary.points, 400u);
  EXPECT_NEAR(summary.half_side, 0.32 * std::sqrt(17.0), 1e-6);
  WorkspaceOptions wo;
  wo.workspace_path = options.output_path;
  std::vector<float> xyz, rgb;
  Workspace::Open(wo).PointCloud(&xyz, &rgb);
  ASSERT_EQ(xyz.size(), 1200u);
  float largest = 0;
  for (float x : xyz) largest = std::max(largest, std::abs(x));
  EXPECT_LE(largest, summary.half_side + 1e-4);
  EXPECT_GT(largest, 0.9 * summary.half_side);
}

TEST(TransformsImport, BadFilesAreRefusedInOneLineWithoutOutput) {
  TempDir dir("transforms_bad");
  const std::string scene = WriteBlenderScene(dir, 3, 0);
  const std::string json_path = scene + "/transforms_train.json";
  TransformsImportOptions options;
  options.transforms_path = scene;
  options.output_path = dir / "ws";
  const auto refused = [&](const std::string& name) {
    Refusal(name, [&] { ImportTransforms(options); });
    EXPECT_FALSE(fs::exists(options.output_path));
    EXPECT_FALSE(fs::exists(options.output_path + ".importing") &&
                 !fs::is_empty(options.output_path + ".importing"));
  };
  const json good = json::parse(std::ifstream(json_path));

  std::ofstream(json_path) << "{ not json";
  refused(json_path);
  json edited = good;
  edited["frames"][1]["transform_matrix"][0][3] = "nan";
  WriteJson(json_path, edited);
  refused(json_path + ": frame 1");
  edited = good;
  for (int r = 0; r < 3; ++r) {  // scaled axes
    for (int c = 0; c < 3; ++c) {
      edited["frames"][2]["transform_matrix"][r][c] =
          2 * good["frames"][2]["transform_matrix"][r][c].get<double>();
    }
  }
  WriteJson(json_path, edited);
  refused(json_path + ": frame 2");
  edited = good;
  edited["frames"][0]["file_path"] = "./train/missing";
  WriteJson(json_path, edited);
  refused(json_path + ": frame 0");
  edited = good;
  edited.erase("camera_angle_x");
  WriteJson(json_path, edited);
  refused(json_path + ": frame 0");
  // A truncated image names the image.
  WriteJson(json_path, good);
  const std::string image = scene + "/train/r_1.png";
  fs::resize_file(image, fs::file_size(image) / 2);
  refused(image);

  // An existing workspace is never overwritten.
  fs::create_directories(options.output_path + "/images");
  std::ofstream(options.output_path + "/keep.txt") << "mine";
  Refusal(options.output_path, [&] { ImportTransforms(options); });
  EXPECT_TRUE(fs::exists(options.output_path + "/keep.txt"));
}

TEST(TransformsImport, TrainHoldsOutTheImportedTestSplit) {
  TempDir dir("transforms_cli");
  const std::string scene = WriteBlenderScene(dir, 6, 4);
  const std::string ws = dir / "ws";
  const testing::CommandResult imported = testing::RunCommand(
      testing::WatergsBin() + " transforms_importer --transforms_path " +
      scene + " --output_path " + ws + " --num_points 300");
  ASSERT_EQ(imported.exit_code, 0) << imported.output;
  EXPECT_NE(imported.output.find("6 training and 4 test views"),
            std::string::npos)
      << imported.output;
  EXPECT_NE(imported.output.find("--background white"), std::string::npos);
  const testing::CommandResult trained =
      testing::RunCommand(testing::WatergsBin() + " train --workspace_path " +
                          ws + " --output_path " + (dir / "out") +
                          " --split train --iterations 20 --background white");
  ASSERT_EQ(trained.exit_code, 0) << trained.output;
  const json result = json::parse(std::ifstream(dir / "out/report.json"));
  EXPECT_EQ(result["num_metric_views"].get<int>(), 4) << result.dump();
  EXPECT_TRUE(std::isfinite(result["psnr"].get<double>()));
}

}  // namespace
}  // namespace watergs
