// transforms.json scenes (NeRF-synthetic, nerfstudio, Instant-NGP) written
// as a COLMAP workspace.
#include "plugin/transforms_import.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "plugin/image_file.h"
#include "plugin/image_header.h"
#include "plugin/reconstruction_io.h"

namespace watergs {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json ReadJsonFile(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  json parsed = json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (parsed.is_discarded() || !parsed.is_object()) {
    FailAt(path,
           "not a JSON object (a transforms file holds {\"frames\": "
           "[...], ...})");
  }
  return parsed;
}

// The number `key` of `frame`, else of `file`; `fallback` when neither has
// it (NaN: required).
double Number(const json& frame, const json& file, const std::string& key,
              const std::string& path, double fallback) {
  for (const json* scope : {&frame, &file}) {
    const auto it = scope->find(key);
    if (it == scope->end() || it->is_null()) continue;
    if (!it->is_number() || !std::isfinite(it->get<double>())) {
      FailAt(path, "\"" + key + "\" is not a finite number");
    }
    return it->get<double>();
  }
  if (std::isnan(fallback)) FailAt(path, "no \"" + key + "\"");
  return fallback;
}

std::string Text(const json& frame, const json& file, const std::string& key,
                 const std::string& fallback) {
  for (const json* scope : {&frame, &file}) {
    const auto it = scope->find(key);
    if (it != scope->end() && it->is_string()) return it->get<std::string>();
  }
  return fallback;
}

Eigen::Matrix4d ReadMatrix(const json& frame, const std::string& where) {
  const auto it = frame.find("transform_matrix");
  if (it == frame.end() || !it->is_array() || it->size() < 3) {
    FailAt(where, "no 4x4 (or 3x4) \"transform_matrix\"");
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (size_t r = 0; r < it->size() && r < 4; ++r) {
    const json& row = (*it)[r];
    if (!row.is_array() || row.size() != 4) {
      FailAt(where, "\"transform_matrix\" row " + std::to_string(r) +
                        " does not hold 4 numbers");
    }
    for (int c = 0; c < 4; ++c) {
      if (!row[c].is_number() || !std::isfinite(row[c].get<double>())) {
        FailAt(where, "\"transform_matrix\" holds a non-finite value");
      }
      m(r, c) = row[c].get<double>();
    }
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  const double error =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm();
  if (error > 1e-3 || rotation.determinant() < 0) {
    FailAt(where,
           "\"transform_matrix\" is not a rotation and a translation "
           "(scaled or mirrored axes)");
  }
  return m;
}

// NeRF-synthetic writes "./train/r_0" without its extension.
std::string ResolveImage(const fs::path& folder, const std::string& file_path,
                         const std::string& where) {
  const fs::path base = (folder / file_path).lexically_normal();
  if (fs::is_regular_file(base)) return base.string();
  for (const char* extension : {".png", ".jpg", ".jpeg", ".JPG", ".PNG"}) {
    const fs::path candidate = base.string() + extension;
    if (fs::is_regular_file(candidate)) return candidate.string();
  }
  FailAt(where, "frame image \"" + file_path + "\" not found (looked for " +
                    base.string() + " with and without .png/.jpg)");
}

// The COLMAP camera a frame's keys describe (width/height may be 0).
Camera FrameCamera(const json& frame, const json& file,
                   const std::string& where) {
  const double nan = std::nan("");
  const double w = Number(frame, file, "w", where, 0);
  const double h = Number(frame, file, "h", where, 0);
  Camera camera;
  camera.width = uint64_t(std::max(0.0, w));
  camera.height = uint64_t(std::max(0.0, h));
  const bool has_fl_x = frame.contains("fl_x") || file.contains("fl_x");
  const bool has_angle_x =
      frame.contains("camera_angle_x") || file.contains("camera_angle_x");
  if (!has_fl_x && !has_angle_x) {
    FailAt(where, "no focal length (\"fl_x\" or \"camera_angle_x\")");
  }
  // Focal lengths from angles need the width: filled in by the caller once
  // the image size is known; stored as negative angles meanwhile.
  const double fx = has_fl_x
                        ? Number(frame, file, "fl_x", where, nan)
                        : -Number(frame, file, "camera_angle_x", where, nan);
  const bool has_fl_y = frame.contains("fl_y") || file.contains("fl_y");
  const bool has_angle_y =
      frame.contains("camera_angle_y") || file.contains("camera_angle_y");
  const double fy = has_fl_y ? Number(frame, file, "fl_y", where, nan)
                    : has_angle_y
                        ? -Number(frame, file, "camera_angle_y", where, nan)
                        : 0;  // 0: as fx
  const double cx = Number(frame, file, "cx", where, -1);
  const double cy = Number(frame, file, "cy", where, -1);
  const double k1 = Number(frame, file, "k1", where, 0);
  const double k2 = Number(frame, file, "k2", where, 0);
  const double k3 = Number(frame, file, "k3", where, 0);
  const double k4 = Number(frame, file, "k4", where, 0);
  const double p1 = Number(frame, file, "p1", where, 0);
  const double p2 = Number(frame, file, "p2", where, 0);
  const std::string model = Text(frame, file, "camera_model", "OPENCV");
  if (model == "OPENCV_FISHEYE") {
    camera.model_id = OpenCVFisheyeCameraModel::kModelId;
    camera.params = {fx, fy, cx, cy, k1, k2, k3, k4};
  } else if (model != "OPENCV" && model != "PINHOLE") {
    FailAt(where, "camera_model \"" + model +
                      "\" is not supported (OPENCV, OPENCV_FISHEYE, PINHOLE)");
  } else if (k3 != 0 || k4 != 0) {
    camera.model_id = FullOpenCVCameraModel::kModelId;
    camera.params = {fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, 0, 0};
  } else if (k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0) {
    camera.model_id = OpenCVCameraModel::kModelId;
    camera.params = {fx, fy, cx, cy, k1, k2, p1, p2};
  } else {
    camera.model_id = PinholeCameraModel::kModelId;
    camera.params = {fx, fy, cx, cy};
  }
  return camera;
}

// Fills the size from the image when the file gave none, focal lengths from
// angles, the principal point at the centre when not given.
void CompleteCamera(Camera* camera, const std::string& image_path,
                    const std::string& where) {
  if (camera->width == 0 || camera->height == 0) {
    int width = 0, height = 0;
    if (!ReadImageHeaderSize(image_path, &width, &height)) {
      const cv::Mat image = DecodeImageFile(image_path);
      width = image.cols;
      height = image.rows;
    }
    camera->width = uint64_t(width);
    camera->height = uint64_t(height);
  }
  std::vector<double>& p = camera->params;
  const double w = double(camera->width), h = double(camera->height);
  if (p[0] < 0) p[0] = 0.5 * w / std::tan(-0.5 * p[0]);
  if (p[1] < 0) p[1] = 0.5 * h / std::tan(-0.5 * p[1]);
  if (p[1] == 0) p[1] = p[0];
  if (p[2] < 0) p[2] = 0.5 * w;
  if (p[3] < 0) p[3] = 0.5 * h;
  if (!(p[0] > 0) || !(p[1] > 0) || !std::isfinite(p[0]) ||
      !std::isfinite(p[1])) {
    FailAt(where,
           "focal length is not positive (a camera angle outside "
           "(0, pi)?)");
  }
}

std::vector<TransformsFrame> ReadFramesOf(const std::string& json_path,
                                          const std::string& split,
                                          int test_stride) {
  const json file = ReadJsonFile(json_path);
  const auto frames = file.find("frames");
  if (frames == file.end() || !frames->is_array() || frames->empty()) {
    FailAt(json_path, "no \"frames\" list");
  }
  const fs::path folder = fs::path(json_path).parent_path();
  std::vector<TransformsFrame> out;
  for (size_t i = 0; i < frames->size(); ++i) {
    if (split == "test" && i % size_t(test_stride) != 0) continue;
    const json& frame = (*frames)[i];
    const std::string where = json_path + ": frame " + std::to_string(i);
    if (!frame.is_object() || !frame.contains("file_path") ||
        !frame["file_path"].is_string()) {
      FailAt(where, "no \"file_path\"");
    }
    TransformsFrame parsed;
    const std::string file_path = frame["file_path"].get<std::string>();
    parsed.image_path = ResolveImage(folder, file_path, where);
    parsed.camera_to_world = ReadMatrix(frame, where);
    parsed.camera = FrameCamera(frame, file, where);
    CompleteCamera(&parsed.camera, parsed.image_path, where);
    parsed.test = split == "test";
    const fs::path relative =
        fs::path(parsed.image_path).lexically_relative(folder);
    parsed.workspace_name =
        split.empty()
            ? relative.generic_string()
            : split + "/" +
                  fs::path(parsed.image_path).filename().generic_string();
    out.push_back(std::move(parsed));
  }
  return out;
}

}  // namespace

std::vector<TransformsFrame> ReadTransforms(const std::string& path,
                                            int test_stride) {
  if (test_stride < 1) FailAt(path, "test stride must be >= 1");
  if (fs::is_regular_file(path)) return ReadFramesOf(path, "", test_stride);
  if (!fs::is_directory(path)) {
    FailAt(path, "not found (give a transforms.json or its folder)");
  }
  const fs::path folder(path);
  if (fs::is_regular_file(folder / "transforms_train.json")) {
    std::vector<TransformsFrame> frames = ReadFramesOf(
        (folder / "transforms_train.json").string(), "train", test_stride);
    if (fs::is_regular_file(folder / "transforms_test.json")) {
      for (TransformsFrame& frame :
           ReadFramesOf((folder / "transforms_test.json").string(), "test",
                        test_stride)) {
        frames.push_back(std::move(frame));
      }
    }
    return frames;
  }
  if (fs::is_regular_file(folder / "transforms.json")) {
    return ReadFramesOf((folder / "transforms.json").string(), "", test_stride);
  }
  FailAt(path, "holds neither transforms.json nor transforms_train.json");
}

Image ImageFromCameraToWorld(const Eigen::Matrix4d& camera_to_world) {
  const Eigen::Matrix3d gl_axes = camera_to_world.topLeftCorner<3, 3>();
  const Eigen::Vector3d centre = camera_to_world.topRightCorner<3, 1>();
  // OpenGL's camera looks down -z with y up; COLMAP's down +z with y down.
  const Eigen::Matrix3d colmap_axes =
      gl_axes * Eigen::Vector3d(1, -1, -1).asDiagonal();
  Eigen::Matrix3d rotation = colmap_axes.transpose();
  // Re-orthonormalise (the files hold 6-8 digits).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(
      rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  rotation = svd.matrixU() * svd.matrixV().transpose();
  Image image;
  const Eigen::Quaterniond q(rotation);
  image.qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  image.tvec = -rotation * centre;
  return image;
}

Eigen::Vector3d LookAtCentre(const std::vector<Image>& images) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero(), mean = b;
  for (const Image& image : images) {
    const Eigen::Vector3d centre = image.ProjectionCenter();
    const Eigen::Vector3d axis = image.RotationMatrix().row(2).transpose();
    const Eigen::Matrix3d off_axis =
        Eigen::Matrix3d::Identity() - axis * axis.transpose();
    a += off_axis;
    b += off_axis * centre;
    mean += centre;
  }
  mean /= double(std::max<size_t>(1, images.size()));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(a);
  const Eigen::Vector3d eigenvalues = solver.eigenvalues();
  // Parallel axes leave one direction unconstrained.
  if (images.size() < 2 || eigenvalues(0) < 1e-3 * eigenvalues(2)) return mean;
  return a.ldlt().solve(b);
}

namespace {

// The frame's image as 8-bit BGR for the workspace: alpha composited on
// `background` (RGB); `had_alpha` tells.
cv::Mat WorkspacePixels(const std::string& path,
                        const std::array<float, 3>& background,
                        bool* had_alpha) {
  // DecodeImageFile validates (truncation, format) and gives RGB in [0, 1].
  const cv::Mat rgb = DecodeImageFile(path);
  const cv::Mat raw = cv::imread(path, cv::IMREAD_UNCHANGED);
  *had_alpha = raw.channels() == 4;
  cv::Mat out(rgb.rows, rgb.cols, CV_8UC3);
  const double alpha_scale = raw.depth() == CV_16U ? 65535.0 : 255.0;
  for (int y = 0; y < rgb.rows; ++y) {
    for (int x = 0; x < rgb.cols; ++x) {
      const cv::Vec3f c = rgb.at<cv::Vec3f>(y, x);
      double a = 1;
      if (*had_alpha) {
        a = raw.depth() == CV_16U ? raw.at<cv::Vec4w>(y, x)[3] / alpha_scale
                                  : raw.at<cv::Vec4b>(y, x)[3] / alpha_scale;
      }
      cv::Vec3b& o = out.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k) {
        const double v = c[k] * a + background[k] * (1 - a);
        o[2 - k] = cv::saturate_cast<uint8_t>(std::lround(255.0 * v));
      }
    }
  }
  return out;
}

// Cameras shared by frames of equal intrinsics.
camera_t CameraIdFor(const Camera& camera, Reconstruction* model) {
  for (const auto& [id, existing] : model->Cameras()) {
    if (existing.model_id == camera.model_id &&
        existing.width == camera.width && existing.height == camera.height &&
        existing.params == camera.params) {
      return id;
    }
  }
  Camera added = camera;
  added.camera_id = camera_t(model->NumCameras() + 1);
  model->AddCamera(added);
  return added.camera_id;
}

// The workspace of `frames` in `staging` (defined below).
TransformsImportSummary WriteWorkspace(
    const std::vector<TransformsFrame>& frames,
    const TransformsImportOptions& options, const fs::path& staging);

}  // namespace

TransformsImportSummary ImportTransforms(
    const TransformsImportOptions& options) {
  if (options.num_points < 1 || options.num_points > 10000000) {
    Fail("transforms_importer: --num_points must be 1 to 10,000,000");
  }
  const std::vector<TransformsFrame> frames =
      ReadTransforms(options.transforms_path, options.test_stride);
  const fs::path output(options.output_path);
  if (fs::exists(output) &&
      (!fs::is_directory(output) || !fs::is_empty(output))) {
    FailAt(options.output_path,
           "exists and is not empty: give a new folder for the workspace");
  }
  const fs::path parent = fs::absolute(output).parent_path();
  CreateDirectories(parent.string());
  const fs::path staging = parent / (output.filename().string() + ".importing");
  fs::remove_all(staging);
  CreateDirectories((staging / "images").string());
  try {
    TransformsImportSummary summary = WriteWorkspace(frames, options, staging);
    if (fs::exists(output)) fs::remove(output);  // an empty folder
    fs::rename(staging, output);
    return summary;
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(staging, ignored);
    throw;
  }
}

namespace {

// The workspace of `frames` in `staging`.
TransformsImportSummary WriteWorkspace(
    const std::vector<TransformsFrame>& frames,
    const TransformsImportOptions& options, const fs::path& staging) {
  TransformsImportSummary summary;
  Reconstruction model;
  std::vector<Image> images;
  std::string test_names;
  ProgressBar bar("import", int64_t(frames.size()));
  for (size_t i = 0; i < frames.size(); ++i) {
    const TransformsFrame& frame = frames[i];
    bool had_alpha = false;
    const cv::Mat pixels =
        WorkspacePixels(frame.image_path, options.background, &had_alpha);
    if (uint64_t(pixels.cols) != frame.camera.width ||
        uint64_t(pixels.rows) != frame.camera.height) {
      FailAt(frame.image_path, "is " + std::to_string(pixels.cols) + "x" +
                                   std::to_string(pixels.rows) +
                                   " but the transforms file says " +
                                   std::to_string(frame.camera.width) + "x" +
                                   std::to_string(frame.camera.height));
    }
    summary.composited += had_alpha;
    std::string name = frame.workspace_name;
    if (had_alpha) name = fs::path(name).replace_extension(".png").string();
    const fs::path target = staging / "images" / name;
    CreateDirectories(target.parent_path().string());
    if (had_alpha) {
      if (!cv::imwrite(target.string(), pixels)) {
        FailAt(target.string(), "could not be written");
      }
    } else {
      fs::copy_file(frame.image_path, target);
    }
    Image image = ImageFromCameraToWorld(frame.camera_to_world);
    image.image_id = image_t(i + 1);
    image.name = name;
    image.camera_id = CameraIdFor(frame.camera, &model);
    images.push_back(image);
    model.AddImage(image);
    model.RegisterImage(image.image_id);
    if (frame.test) {
      test_names += name + "\n";
      ++summary.test_views;
    } else {
      ++summary.train_views;
    }
    bar.Update(int64_t(i + 1));
  }
  bar.Finish();
  // Random initial points, grey as Inria's for synthetic scenes.
  summary.centre = LookAtCentre(images);
  std::vector<double> distances;
  for (const Image& image : images) {
    distances.push_back((image.ProjectionCenter() - summary.centre).norm());
  }
  std::nth_element(distances.begin(), distances.begin() + distances.size() / 2,
                   distances.end());
  summary.half_side =
      options.points_half_side * distances[distances.size() / 2];
  std::mt19937_64 random(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int p = 0; p < options.num_points; ++p) {
    Point3D point;
    point.xyz = summary.centre +
                summary.half_side *
                    Eigen::Vector3d(unit(random), unit(random), unit(random));
    point.rgb.setConstant(128);
    model.AddPoint3D(point3D_t(p + 1), point);
  }
  WriteReconstruction(model, (staging / "sparse" / "0").string(),
                      ModelFormat::kText);
  if (!test_names.empty()) {
    AtomicWriteFile((staging / "test_views.txt").string(), test_names);
  }
  summary.cameras = model.NumCameras();
  summary.points = model.NumPoints3D();
  return summary;
}

}  // namespace

}  // namespace watergs
