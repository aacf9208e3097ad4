// Test helpers: synthetic COLMAP models (cameras on a ring around random
// points, observations projected through the real camera models), temp
// folders and running commands.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "plugin/reconstruction.h"

namespace watergs::testing {

// Plausible parameters for each COLMAP model on a width x height image:
// focal ~0.8 width, principal point off-centre, moderate distortion.
inline std::vector<double> ExampleCameraParams(int model_id, int width,
                                               int height) {
  const double f = 0.8 * width, fy = 0.82 * width;
  const double cx = width / 2.0 + 1.25, cy = height / 2.0 - 0.75;
  switch (model_id) {
    case 0:
      return {f, cx, cy};
    case 1:
      return {f, fy, cx, cy};
    case 2:
      return {f, cx, cy, -0.05};
    case 3:
      return {f, cx, cy, -0.05, 0.01};
    case 4:
      return {f, fy, cx, cy, -0.04, 0.01, 0.001, -0.0015};
    case 5:
      return {f, fy, cx, cy, 0.02, -0.01, 0.003, -0.001};
    case 6:
      return {f,     fy,     cx,    cy,   -0.03,  0.01,
              0.001, -0.001, 0.002, 0.01, -0.002, 0.001};
    case 7:
      return {f, fy, cx, cy, 0.9};
    case 8:
      return {f, cx, cy, 0.02};
    case 9:
      return {f, cx, cy, 0.02, -0.005};
    case 10:
      return {f,     fy,     cx,    cy,      0.02,  -0.005,
              0.001, -0.001, 0.001, -0.0005, 0.001, -0.001};
    default:
      return {};
  }
}

struct SyntheticModelOptions {
  // One camera per entry, with this COLMAP model id.
  std::vector<int> model_ids = {1};
  // Images on a ring of radius 4 around the origin, looking at it.
  int num_images = 6;
  // Candidate points in [-2.5, 2.5]^3; those seen by < 2 images are dropped.
  int num_points = 150;
  // Image size of every camera.
  int width = 64;
  int height = 48;
  // Seeds colours, positions and record order.
  uint32_t seed = 1;
};

// World-to-camera rotation of a camera at `center` looking at the origin.
inline Eigen::Matrix3d LookAtOrigin(const Eigen::Vector3d& center) {
  const Eigen::Vector3d z = (-center).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitZ().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  return R;
}

// A consistent model: ids are scattered and inserted out of order (so that
// hash-map order matters), some keypoints observe nothing, some points have
// no error (-1), qvecs are slightly unnormalized.
inline Reconstruction MakeSyntheticReconstruction(
    const SyntheticModelOptions& options) {
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Reconstruction model;
  const int num_cameras = options.model_ids.size();
  for (int c = num_cameras - 1; c >= 0; --c) {
    model.AddCamera({camera_t(3 * c + 2), options.model_ids[c],
                     uint64_t(options.width), uint64_t(options.height),
                     ExampleCameraParams(options.model_ids[c], options.width,
                                         options.height)});
  }
  std::vector<Image> images(options.num_images);
  for (int i = 0; i < options.num_images; ++i) {
    const double angle = 2 * M_PI * i / options.num_images;
    const Eigen::Vector3d center(4 * std::cos(angle), 4 * std::sin(angle),
                                 0.5 * (i % 2));
    const Eigen::Matrix3d R = LookAtOrigin(center);
    const Eigen::Quaterniond q(R);
    images[i].image_id = 7 * i + 5;
    images[i].name = "frame_" + std::to_string(1000 + i) + ".png";
    images[i].camera_id = 3 * (i % num_cameras) + 2;
    images[i].qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()) * 1.0000003;
    images[i].tvec = -R * center;
  }
  std::vector<std::pair<point3D_t, Point3D>> points;
  for (int p = 0; p < options.num_points; ++p) {
    const point3D_t id = 1 + uint64_t(p) * 7919 % 100003;
    Point3D point;
    point.xyz = 2.5 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    point.rgb << uint8_t(rng() % 256), uint8_t(rng() % 256),
        uint8_t(rng() % 256);
    point.error = p % 10 == 3 ? -1.0 : 0.2 + 0.65 * (unit(rng) + 1);
    for (Image& image : images) {
      const Camera& camera = model.GetCamera(image.camera_id);
      const Eigen::Vector3d X = image.RotationMatrix() * point.xyz + image.tvec;
      if (X.z() < 0.5) continue;
      const Eigen::Vector2d xy = camera.WorldToImage(X.head<2>() / X.z());
      if (xy.x() < 0 || xy.y() < 0 || xy.x() >= options.width ||
          xy.y() >= options.height) {
        continue;
      }
      point.track.push_back({image.image_id, point2D_t(image.points2D.size())});
      image.points2D.push_back({xy + 0.1 * Eigen::Vector2d(unit(rng), 0), id});
    }
    if (point.track.size() < 2) {
      for (const TrackElement& e : point.track) {
        auto& image = *std::find_if(images.begin(), images.end(), [&](auto& i) {
          return i.image_id == e.image_id;
        });
        image.points2D[e.point2D_idx].point3D_id = kInvalidPoint3DId;
      }
      continue;
    }
    points.emplace_back(id, std::move(point));
  }
  std::shuffle(points.begin(), points.end(), rng);
  std::vector<int> order(images.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  for (int i : order) {
    const image_t id = images[i].image_id;
    model.AddImage(images[i]);
    model.RegisterImage(id);
  }
  for (auto& [id, point] : points) model.AddPoint3D(id, std::move(point));
  return model;
}

// A fresh empty folder under the system temp dir, removed on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    static std::random_device device;
    path_ = std::filesystem::temp_directory_path() /
            ("watergs_" + tag + "_" + std::to_string(device()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::string path() const { return path_.string(); }
  std::string operator/(const std::string& name) const {
    return (path_ / name).string();
  }

 private:
  std::filesystem::path path_;
};

struct CommandResult {
  // Exit status (-1 if it could not run).
  int exit_code = -1;
  // stdout and stderr together.
  std::string output;
};

// Runs `command` through the shell, capturing stdout and stderr.
inline CommandResult RunCommand(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) {
    result.output.append(buffer.data(), n);
  }
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// The watergs CLI under test (CTest sets WATERGS_BIN).
inline std::string WatergsBin() {
  const char* bin = std::getenv("WATERGS_BIN");
  return bin ? bin : std::string(WATERGS_BINARY_DIR) + "/plugin/watergs";
}

}  // namespace watergs::testing
