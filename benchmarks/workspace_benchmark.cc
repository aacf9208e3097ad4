// COLMAP-layer timings: model read/write in both formats for a large
// synthetic model, undistortion map and warp at 1080p, and view loading of
// the demo scene (cold decode and cache hit). Prints medians.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "plugin/reconstruction_io.h"
#include "plugin/undistortion.h"
#include "plugin/workspace.h"

namespace {

using watergs::Camera;
using watergs::Reconstruction;

// Median wall time in ms of `runs` calls.
double MedianMs(int runs, const std::function<void()>& fn) {
  std::vector<double> times;
  for (int i = 0; i < runs; ++i) {
    const auto start = std::chrono::steady_clock::now();
    fn();
    times.push_back(std::chrono::duration<double, std::milli>(
                        std::chrono::steady_clock::now() - start)
                        .count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

// num_images images with points_per_image keypoints; each point observed by
// `track` consecutive images.
Reconstruction RandomModel(int num_images, int num_points, int track) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  Reconstruction model;
  model.AddCamera({1, 4, 1920, 1080, {1500, 1500, 960, 540, -0.1, 0.01, 0, 0}});
  std::vector<watergs::Image> images(num_images);
  for (int i = 0; i < num_images; ++i) {
    images[i].image_id = i + 1;
    images[i].camera_id = 1;
    images[i].name = "img_" + std::to_string(i) + ".jpg";
    images[i].tvec << unit(rng), unit(rng), unit(rng);
  }
  for (int p = 0; p < num_points; ++p) {
    watergs::Point3D point;
    point.xyz << unit(rng), unit(rng), unit(rng);
    point.error = unit(rng);
    for (int k = 0; k < track; ++k) {
      watergs::Image& image = images[(p + k) % num_images];
      point.track.push_back(
          {image.image_id, watergs::point2D_t(image.points2D.size())});
      image.points2D.push_back(
          {Eigen::Vector2d(1920 * unit(rng), 1080 * unit(rng)),
           watergs::point3D_t(p + 1)});
    }
    model.AddPoint3D(p + 1, point);
  }
  for (auto& image : images) {
    const auto id = image.image_id;
    model.AddImage(std::move(image));
    model.RegisterImage(id);
  }
  return model;
}

void BenchmarkModelIO() {
  const auto dir = std::filesystem::temp_directory_path() / "watergs_io_bench";
  const Reconstruction model = RandomModel(300, 200000, 4);
  std::printf("model: %zu images, %zu points, %zu observations\n",
              model.NumRegImages(), model.NumPoints3D(),
              model.ComputeNumObservations());
  for (const auto format :
       {watergs::ModelFormat::kBinary, watergs::ModelFormat::kText}) {
    const std::string path =
        (dir / (format == watergs::ModelFormat::kBinary ? "bin" : "txt"))
            .string();
    const double write_ms =
        MedianMs(5, [&] { watergs::WriteReconstruction(model, path, format); });
    const double read_ms =
        MedianMs(5, [&] { watergs::ReadReconstruction(path); });
    std::printf("%s: write %.1f ms, read %.1f ms (median of 5)\n",
                format == watergs::ModelFormat::kBinary ? "BIN" : "TXT",
                write_ms, read_ms);
  }
  std::filesystem::remove_all(dir);
}

void BenchmarkUndistortion() {
  const Camera camera{
      1, 4, 1920, 1080, {1500, 1500, 960, 540, -0.1, 0.01, 0.001, -0.001}};
  Camera pinhole;
  const double camera_ms =
      MedianMs(5, [&] { pinhole = watergs::UndistortCamera(camera); });
  watergs::WarpMap map;
  const double map_ms =
      MedianMs(5, [&] { map = watergs::ComputeWarpMap(camera, pinhole); });
  const cv::Mat image(1080, 1920, CV_32FC3, cv::Scalar(0.5, 0.25, 0.75));
  const double warp_ms =
      MedianMs(9, [&] { cv::Mat out = watergs::WarpImage(image, map); });
  std::printf(
      "OPENCV 1920x1080 -> PINHOLE %llux%llu: camera %.1f ms, map %.1f ms, "
      "warp (float RGB) %.1f ms (medians)\n",
      (unsigned long long)pinhole.width, (unsigned long long)pinhole.height,
      camera_ms, map_ms, warp_ms);
}

void BenchmarkDemoScene() {
  const std::string scene =
      std::string(WATERGS_SOURCE_DIR) + "/datasets_scripts/demo_scene";
  if (!std::filesystem::exists(scene + "/sparse/0")) {
    std::printf("demo scene absent: view loading not measured\n");
    return;
  }
  watergs::WorkspaceOptions options;
  options.workspace_path = scene;
  const double open_ms =
      MedianMs(5, [&] { watergs::Workspace::Open(options); });
  const watergs::Workspace workspace = watergs::Workspace::Open(options);
  size_t view = 0;
  const double cold_ms =
      MedianMs(int(workspace.NumViews()), [&] { workspace.LoadView(view++); });
  view = 0;
  const double hit_ms =
      MedianMs(int(workspace.NumViews()), [&] { workspace.LoadView(view++); });
  std::printf(
      "demo scene (%zu views %dx%d): Open %.1f ms, LoadView decode %.2f ms, "
      "cache hit %.3f ms (medians)\n",
      workspace.NumViews(), workspace.ViewCamera(0).width,
      workspace.ViewCamera(0).height, open_ms, cold_ms, hit_ms);
}

}  // namespace

int main() {
  BenchmarkModelIO();
  BenchmarkUndistortion();
  BenchmarkDemoScene();
  return 0;
}
