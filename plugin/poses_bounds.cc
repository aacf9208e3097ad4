// LLFF poses_bounds.npy -> Reconstruction (see poses_bounds.h).
#include "plugin/poses_bounds.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <tuple>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {

namespace fs = std::filesystem;

namespace {

// The value of `key` in a .npy header dict ("'descr': '<f8', ..."), raw.
std::string HeaderField(const std::string& header, const std::string& key) {
  const size_t at = header.find("'" + key + "':");
  if (at == std::string::npos) return "";
  size_t begin = at + key.size() + 3;
  while (begin < header.size() && header[begin] == ' ') ++begin;
  const char close = header[begin] == '(' ? ')' : ',';
  const size_t end = header.find(close, begin + 1);
  if (end == std::string::npos) return "";
  return header.substr(begin, end - begin + (close == ')' ? 1 : 0));
}

// Rows x 17 doubles of a little-endian, C-order float64 .npy file.
std::vector<double> ReadNpyMatrix17(const std::string& path, size_t* rows) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  static const char kMagic[] = "\x93NUMPY";
  if (bytes.size() < 10 || std::memcmp(bytes.data(), kMagic, 6) != 0) {
    FailAt(path, "not a .npy file (bad magic)");
  }
  const int major = bytes[6];
  const size_t length_bytes = major == 1 ? 2 : 4;
  size_t header_length = 0;
  for (size_t i = 0; i < length_bytes; ++i) {
    header_length |= size_t(bytes[8 + i]) << (8 * i);
  }
  const size_t data_at = 8 + length_bytes + header_length;
  if (major < 1 || major > 3 || data_at > bytes.size()) {
    FailAt(path, "truncated or unknown .npy header");
  }
  const std::string header(bytes.begin() + 8 + length_bytes,
                           bytes.begin() + data_at);
  const std::string descr = HeaderField(header, "descr");
  if (descr != "'<f8'") {
    FailAt(path, "holds " + descr + " values, not float64 ('<f8')");
  }
  if (HeaderField(header, "fortran_order") != "False") {
    FailAt(path, "is in Fortran order (expected C order)");
  }
  const std::string shape = HeaderField(header, "shape");
  size_t n = 0, m = 0;
  if (std::sscanf(shape.c_str(), "(%zu, %zu)", &n, &m) != 2 || m != 17) {
    FailAt(path, "has shape " + shape + ", not (N, 17) as LLFF writes");
  }
  if (bytes.size() - data_at != n * 17 * sizeof(double)) {
    FailAt(path, "holds " + std::to_string(bytes.size() - data_at) +
                     " data bytes for shape " + shape);
  }
  std::vector<double> values(n * 17);
  std::memcpy(values.data(), bytes.data() + data_at,
              values.size() * sizeof(double));
  for (const double v : values) {
    if (!std::isfinite(v)) FailAt(path, "holds a non-finite value");
  }
  *rows = n;
  return values;
}

}  // namespace

std::vector<std::string> PosesBoundsImageNames(const std::string& path) {
  const fs::path folder = fs::path(path).parent_path() / "images";
  if (!fs::is_directory(folder)) {
    FailAt(path, "no images/ folder beside it to name its rows");
  }
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (entry.is_regular_file() &&
        (extension == ".jpg" || extension == ".jpeg" || extension == ".png")) {
      names.push_back(entry.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

Reconstruction ReadPosesBounds(const std::string& path,
                               const std::vector<std::string>& image_names) {
  size_t rows = 0;
  const std::vector<double> values = ReadNpyMatrix17(path, &rows);
  if (rows != image_names.size()) {
    FailAt(path, "has " + std::to_string(rows) + " poses for " +
                     std::to_string(image_names.size()) + " photos");
  }
  Reconstruction model;
  std::map<std::tuple<double, double, double>, camera_t> cameras;
  for (size_t i = 0; i < rows; ++i) {
    const double* row = values.data() + 17 * i;
    // row[5 * r + c]: row r of the 3 x 5 matrix.
    auto at = [&](int r, int c) { return row[5 * r + c]; };
    Eigen::Matrix3d camera_to_world;
    for (int r = 0; r < 3; ++r) {
      // COLMAP's axes (right, down, forward) from LLFF's (down, right, back).
      camera_to_world(r, 0) = at(r, 1);
      camera_to_world(r, 1) = at(r, 0);
      camera_to_world(r, 2) = -at(r, 2);
    }
    const Eigen::Vector3d center(at(0, 3), at(1, 3), at(2, 3));
    const double height = at(0, 4), width = at(1, 4), focal = at(2, 4);
    if (!(height >= 1 && width >= 1 && focal > 0) ||
        std::abs(camera_to_world.determinant() - 1) > 1e-3) {
      FailAt(path, "row " + std::to_string(i) +
                       " is not a rotation with a positive size and focal "
                       "length");
    }
    auto [it, added] = cameras.emplace(std::make_tuple(height, width, focal),
                                       camera_t(cameras.size() + 1));
    if (added) {
      model.AddCamera(Camera{it->second,
                             PinholeCameraModel::kModelId,
                             uint64_t(std::lround(width)),
                             uint64_t(std::lround(height)),
                             {focal, focal, width / 2, height / 2}});
    }
    const Eigen::Matrix3d world_to_camera = camera_to_world.transpose();
    const Eigen::Quaterniond q(world_to_camera);
    Image image;
    image.image_id = image_t(i + 1);
    image.name = image_names[i];
    image.camera_id = it->second;
    image.qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
    image.tvec = -world_to_camera * center;
    model.AddImage(image);
    model.RegisterImage(image.image_id);
  }
  return model;
}

}  // namespace watergs
