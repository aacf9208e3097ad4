// Workspace: model + views + render cameras + cached image loading.
#include "plugin/workspace.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <list>
#include <map>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <tuple>
#include <unordered_map>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"
#include "plugin/image_header.h"
#include "plugin/reconstruction_io.h"
#include "plugin/undistortion.h"

namespace watergs {

namespace fs = std::filesystem;

// Thread-safe LRU cache of decoded views plus the warp maps of distorted
// cameras (few cameras are distorted at once, so maps are kept per camera).
class ImageLoader {
 public:
  explicit ImageLoader(size_t capacity_bytes) : capacity_(capacity_bytes) {}

  // The cached view, or nullptr-equivalent false.
  bool Find(size_t view, ImageRGB* image) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = entries_.find(view);
    if (it == entries_.end()) return false;
    order_.splice(order_.begin(), order_, it->second.position);
    *image = it->second.image;
    return true;
  }
  void Insert(size_t view, const ImageRGB& image) {
    const size_t bytes = image.data.size() * sizeof(float);
    std::lock_guard<std::mutex> lock(mutex_);
    if (bytes > capacity_ || entries_.count(view)) return;
    while (used_ + bytes > capacity_ && !order_.empty()) {
      const size_t oldest = order_.back();
      used_ -= entries_.at(oldest).image.data.size() * sizeof(float);
      entries_.erase(oldest);
      order_.pop_back();
    }
    order_.push_front(view);
    entries_[view] = {image, order_.begin()};
    used_ += bytes;
  }
  // Warp map from `source` to `target`, computed once per source camera.
  // At most kMaxMaps are kept (oldest dropped first): COLMAP models often
  // have one camera per image, and a 1080p map takes 16 MB.
  std::shared_ptr<const WarpMap> Map(const Camera& source,
                                     const Camera& target) {
    constexpr size_t kMaxMaps = 8;
    const MapKey key{source.camera_id, source.width, source.height};
    std::lock_guard<std::mutex> lock(mutex_);
    auto& map = maps_[key];
    if (!map) {
      map = std::make_shared<const WarpMap>(ComputeWarpMap(source, target));
      map_order_.push_back(key);
      if (map_order_.size() > kMaxMaps) {
        maps_.erase(map_order_.front());
        map_order_.pop_front();
      }
    }
    return maps_.at(key);
  }

 private:
  struct Entry {
    // The decoded view.
    ImageRGB image;
    // Its place in order_ (most recent first).
    std::list<size_t>::iterator position;
  };
  std::mutex mutex_;
  size_t capacity_;
  size_t used_ = 0;
  std::list<size_t> order_;
  std::unordered_map<size_t, Entry> entries_;
  // Keyed by source camera id and size (images_<k> files may differ by a
  // pixel).
  using MapKey = std::tuple<camera_t, uint64_t, uint64_t>;
  std::map<MapKey, std::shared_ptr<const WarpMap>> maps_;
  // Keys of maps_ in creation order.
  std::list<MapKey> map_order_;
};

namespace {

std::string Quoted(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) {
    quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  }
  return quoted + "'";
}

// <parent>/<folder>_<k> for image folder <parent>/<folder>.
std::string DownscaledImagePath(const std::string& image_path, int downscale) {
  fs::path path = fs::path(image_path).lexically_normal();
  if (path.filename().empty()) path = path.parent_path();
  return (path.parent_path() /
          (path.filename().string() + "_" + std::to_string(downscale)))
      .string();
}

// Runs `colmap image_undistorter` into `output_path` unless it already
// holds a model; returns the undistorted model folder.
std::string RunColmapUndistorter(const WorkspaceOptions& options,
                                 const std::string& model_path) {
  const std::string sparse =
      (fs::path(options.undistorted_path) / "sparse").string();
  if (fs::is_regular_file(fs::path(sparse) / "cameras.bin")) return sparse;
  fs::create_directories(options.undistorted_path);
  const std::string log =
      (fs::path(options.undistorted_path) / "image_undistorter.log").string();
  const std::string command =
      "QT_QPA_PLATFORM=offscreen colmap image_undistorter --image_path " +
      Quoted(options.image_path) + " --input_path " + Quoted(model_path) +
      " --output_path " + Quoted(options.undistorted_path) +
      " --output_type COLMAP > " + Quoted(log) + " 2>&1";
  const int status = std::system(command.c_str());
  if (status != 0) {
    FailAt(options.undistorted_path,
           "colmap image_undistorter failed (status " + std::to_string(status) +
               "); see " + log);
  }
  return sparse;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

Workspace::Workspace(Workspace&&) noexcept = default;
Workspace& Workspace::operator=(Workspace&&) noexcept = default;
Workspace::~Workspace() = default;

namespace {

// The workspace a model folder belongs to: <ws> for <ws>/sparse/<n> and
// <ws>/sparse, else the model folder's parent.
fs::path WorkspaceOfModel(const std::string& input_path) {
  fs::path path = fs::path(input_path).lexically_normal();
  if (path.filename().empty()) path = path.parent_path();
  if (path.parent_path().filename() == "sparse") {
    return path.parent_path().parent_path();
  }
  return path.parent_path();
}

WorkspaceOptions WithDefaults(const WorkspaceOptions& options) {
  WorkspaceOptions filled = options;
  if (filled.workspace_path.empty() && filled.input_path.empty()) {
    Fail("workspace: give --workspace_path or --sparse_path");
  }
  if (filled.downscale < 1) Fail("workspace: downscale must be >= 1");
  const fs::path root = filled.workspace_path.empty()
                            ? WorkspaceOfModel(filled.input_path)
                            : fs::path(filled.workspace_path);
  if (filled.image_path.empty()) filled.image_path = (root / "images").string();
  if (filled.undistorted_path.empty()) {
    filled.undistorted_path = (root / "undistorted_watergs").string();
  }
  return filled;
}

// `camera` for images resized to width x height: focal lengths and
// principal point scale with the size; distortion (on normalized
// coordinates) is unchanged.
Camera RescaleCamera(const Camera& camera, int width, int height) {
  Camera scaled = camera;
  const double sx = width / double(camera.width);
  const double sy = height / double(camera.height);
  const bool single = CameraModelHasSingleFocalLength(camera.model_id);
  scaled.width = width;
  scaled.height = height;
  scaled.params[0] *= single ? 0.5 * (sx + sy) : sx;
  if (!single) scaled.params[1] *= sy;
  scaled.params[single ? 1 : 2] *= sx;
  scaled.params[single ? 2 : 3] *= sy;
  return scaled;
}

// Whether a photo of width x height is its camera's width_c x height_c
// image resized (each side within rounding of the other's scale).
bool SameAspect(int width, int height, uint64_t width_c, uint64_t height_c) {
  const long height_at_width = std::lround(double(height_c) * width / width_c);
  const long width_at_height = std::lround(double(width_c) * height / height_c);
  return height_at_width == height || width_at_height == width;
}

// Cameras whose photos were all resized to one other size at the same
// aspect ratio (LLFF copies at 800x600 of a 4032x3024 camera): their
// intrinsics are scaled to the photos, as Inria's and gsplat's loaders take
// the field of view from the camera and the pixels from the image. Returns
// one notice per scaled camera; photos of one camera at several sizes, or
// at another aspect ratio, are left to CheckViewImages' error.
std::vector<std::string> ScaleCamerasToPhotos(Reconstruction* model,
                                              const std::vector<image_t>& views,
                                              const std::string& image_path) {
  std::map<camera_t, std::map<std::pair<int, int>, int>> sizes;
  for (const image_t id : views) {
    const Image& image = model->GetImage(id);
    int width = 0, height = 0;
    const std::string path = (fs::path(image_path) / image.name).string();
    if (!fs::is_regular_file(path) ||
        !ReadImageHeaderSize(path, &width, &height)) {
      return {};
    }
    ++sizes[image.camera_id][{width, height}];
  }
  std::vector<std::string> notices;
  for (const auto& [camera_id, counts] : sizes) {
    if (counts.size() != 1) continue;
    const auto [width, height] = counts.begin()->first;
    Camera& camera = model->GetCamera(camera_id);
    if (uint64_t(width) == camera.width && uint64_t(height) == camera.height) {
      continue;
    }
    if (!SameAspect(width, height, camera.width, camera.height)) continue;
    notices.push_back("notice: " + image_path + ": the " +
                      std::to_string(counts.begin()->second) +
                      " photos of camera " + std::to_string(camera_id) +
                      " are " + SizeText(width, height) + ", the camera " +
                      SizeText(camera.width, camera.height) +
                      ": its intrinsics are scaled to the photos");
    camera = RescaleCamera(camera, width, height);
  }
  return notices;
}

// Every view's image exists and, where the header tells, has its camera's
// size (the rest is checked when decoded).
void CheckViewImages(const Reconstruction& model,
                     const std::vector<image_t>& views,
                     const std::string& image_path,
                     const std::string& model_path) {
  for (const image_t id : views) {
    const Image& image = model.GetImage(id);
    const Camera& camera = model.GetCamera(image.camera_id);
    const std::string path = (fs::path(image_path) / image.name).string();
    if (!fs::is_regular_file(path)) {
      FailAt(path, "missing (image " + std::to_string(id) + " of the model " +
                       model_path + ")");
    }
    int width = 0, height = 0;
    if (ReadImageHeaderSize(path, &width, &height) &&
        (uint64_t(width) != camera.width ||
         uint64_t(height) != camera.height)) {
      FailAt(path, "is " + SizeText(width, height) + " but its camera " +
                       std::to_string(camera.camera_id) + " is " +
                       SizeText(camera.width, camera.height) +
                       (SameAspect(width, height, camera.width, camera.height)
                            ? " (and the camera's other photos differ)"
                            : " (another aspect ratio: only photos resized "
                              "at the camera's are scaled)"));
    }
  }
}

// `pinhole` cropped (centred, whole pixels) to a multiple of `k` in each
// dimension, so that its views are exact k-fold reductions: an undistorted
// camera 479 pixels wide, rendered at round(479 / 2) = 240, resampled the
// photos at 0.501 and blurred them (docs/reconstruct.md).
Camera CropToMultiple(Camera pinhole, int k) {
  const uint64_t width = pinhole.width / k * k;
  const uint64_t height = pinhole.height / k * k;
  if (k <= 1 || width == 0 || height == 0) return pinhole;
  pinhole.params[2] -= double((pinhole.width - width) / 2);
  pinhole.params[3] -= double((pinhole.height - height) / 2);
  pinhole.width = width;
  pinhole.height = height;
  return pinhole;
}

// The pinhole render camera of `image`: `pinhole` intrinsics scaled to
// round(size / downscale), COLMAP's world-to-camera pose.
RenderCamera MakeRenderCamera(const Image& image, const Camera& pinhole,
                              int downscale) {
  RenderCamera camera;
  camera.width =
      std::max<long>(1, std::lround(pinhole.width / double(downscale)));
  camera.height =
      std::max<long>(1, std::lround(pinhole.height / double(downscale)));
  const double sx = camera.width / double(pinhole.width);
  const double sy = camera.height / double(pinhole.height);
  camera.fx = pinhole.params[0] * sx;
  camera.fy = pinhole.params[1] * sy;
  camera.cx = pinhole.params[2] * sx;
  camera.cy = pinhole.params[3] * sy;
  camera.R = image.RotationMatrix();
  camera.t = image.tvec;
  return camera;
}

// The PINHOLE camera of a render camera.
Camera PinholeOf(const RenderCamera& render, camera_t camera_id) {
  return Camera{camera_id,
                PinholeCameraModel::kModelId,
                uint64_t(render.width),
                uint64_t(render.height),
                {render.fx, render.fy, render.cx, render.cy}};
}

}  // namespace

// <workspace>/test_views.txt: every line an image name of the model.
void Workspace::ReadTestViews(Workspace* workspace,
                              const WorkspaceOptions& given) {
  const fs::path root = given.workspace_path.empty()
                            ? WorkspaceOfModel(given.input_path)
                            : fs::path(given.workspace_path);
  const fs::path path = root / "test_views.txt";
  if (!fs::is_regular_file(path)) return;
  std::map<std::string, size_t> view_of_name;
  for (size_t v = 0; v < workspace->views_.size(); ++v) {
    view_of_name[workspace->ViewName(v)] = v;
  }
  workspace->listed_test_.assign(workspace->views_.size(), false);
  workspace->test_views_path_ = path.string();
  const std::vector<uint8_t> bytes = ReadFileBytes(path.string());
  std::istringstream lines(std::string(bytes.begin(), bytes.end()));
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) {
      line.pop_back();
    }
    if (line.empty() || line[0] == '#') continue;
    const auto it = view_of_name.find(line);
    if (it == view_of_name.end()) {
      FailAt(path.string(),
             "line " + std::to_string(number) + ": '" + Printable(line) +
                 "' is not an image of the model " + workspace->model_path_);
    }
    workspace->listed_test_[it->second] = true;
  }
}

// Fills default paths, reads the model (through colmap image_undistorter if
// asked), sorts the views and checks every image against its camera.
Workspace Workspace::Open(const WorkspaceOptions& options) {
  Workspace workspace;
  WorkspaceOptions& opts = workspace.options_;
  opts = WithDefaults(options);
  workspace.model_path_ = FindModelPath(
      opts.input_path.empty() ? opts.workspace_path : opts.input_path);
  workspace.reconstruction_ = ReadReconstruction(workspace.model_path_);
  if (fs::is_directory(opts.image_path)) {
    workspace.notices_ = ScaleCamerasToPhotos(
        &workspace.reconstruction_, workspace.reconstruction_.RegImageIds(),
        opts.image_path);
    for (const std::string& notice : workspace.notices_) {
      std::cerr << notice << "\n";
    }
  }
  for (const auto& [id, camera] : workspace.reconstruction_.Cameras()) {
    workspace.undistorted_ |= camera.HasDistortion();
  }
  if (workspace.undistorted_ && opts.use_colmap_undistorter) {
    std::string input_model = workspace.model_path_;
    if (!workspace.notices_.empty()) {
      // The undistorter reads the model from disk: give it the scaled one.
      input_model = (fs::path(opts.undistorted_path) / "scaled_input").string();
      WriteReconstruction(workspace.reconstruction_, input_model,
                          ModelFormat::kBinary);
    }
    workspace.model_path_ = RunColmapUndistorter(opts, input_model);
    opts.image_path = (fs::path(opts.undistorted_path) / "images").string();
    workspace.reconstruction_ = ReadReconstruction(workspace.model_path_);
  }
  workspace.has_images_ = fs::is_directory(opts.image_path);
  if (!workspace.has_images_ && !opts.images_optional) {
    FailAt(opts.image_path, "image folder not found");
  }
  const Reconstruction& model = workspace.reconstruction_;
  workspace.views_ = model.RegImageIds();
  std::sort(workspace.views_.begin(), workspace.views_.end(),
            [&](image_t a, image_t b) {
              return model.GetImage(a).name < model.GetImage(b).name;
            });
  if (workspace.has_images_) {
    CheckViewImages(model, workspace.views_, opts.image_path,
                    workspace.model_path_);
  }
  ReadTestViews(&workspace, options);
  for (const auto& [id, camera] : model.Cameras()) {
    const Camera pinhole = UndistortCamera(camera);
    workspace.pinhole_cameras_[id] =
        camera.HasDistortion() ? CropToMultiple(pinhole, opts.downscale)
                               : pinhole;
  }
  for (const image_t id : workspace.views_) {
    const Image& image = model.GetImage(id);
    workspace.view_cameras_.push_back(MakeRenderCamera(
        image, workspace.pinhole_cameras_.at(image.camera_id), opts.downscale));
  }
  workspace.loader_ = std::make_unique<ImageLoader>(opts.image_cache_bytes);
  return workspace;
}

const std::string& Workspace::ViewName(size_t view) const {
  return ViewImage(view).name;
}

const Image& Workspace::ViewImage(size_t view) const {
  if (view >= views_.size()) {
    Fail("workspace: view " + std::to_string(view) + " out of range (" +
         std::to_string(views_.size()) + " views)");
  }
  return reconstruction_.GetImage(views_[view]);
}

RenderCamera Workspace::ViewCamera(size_t view) const {
  ViewImage(view);
  return view_cameras_[view];
}

// At downscale k, <images>_k/<name> is read when that folder exists (its
// size within one pixel of round(camera size / k)); otherwise the full image
// is decoded. Distorted images are then warped to the view's pinhole camera
// (from an images_k file, through the COLMAP camera rescaled to its size);
// whatever is not yet at the view size is resized with INTER_AREA.
ImageRGB Workspace::LoadView(size_t view) const {
  ImageRGB cached;
  if (loader_->Find(view, &cached)) return cached;
  const Image& image = ViewImage(view);
  const Camera& camera = reconstruction_.GetCamera(image.camera_id);
  const RenderCamera& target = view_cameras_[view];
  const std::string downscaled_folder =
      DownscaledImagePath(options_.image_path, options_.downscale);
  const bool from_downscaled =
      options_.downscale > 1 && fs::is_directory(downscaled_folder);
  const std::string path =
      (fs::path(from_downscaled ? downscaled_folder : options_.image_path) /
       image.name)
          .string();
  cv::Mat rgb = DecodeImageFile(path);
  const long expected_width =
      from_downscaled ? std::lround(camera.width / double(options_.downscale))
                      : long(camera.width);
  const long expected_height =
      from_downscaled ? std::lround(camera.height / double(options_.downscale))
                      : long(camera.height);
  const long tolerance = from_downscaled ? 1 : 0;
  if (std::abs(rgb.cols - expected_width) > tolerance ||
      std::abs(rgb.rows - expected_height) > tolerance) {
    FailAt(path, "is " + SizeText(rgb.cols, rgb.rows) + " but its camera " +
                     std::to_string(camera.camera_id) +
                     (from_downscaled ? " at downscale " +
                                            std::to_string(options_.downscale)
                                      : std::string()) +
                     " is " + SizeText(expected_width, expected_height));
  }
  if (camera.HasDistortion()) {
    const Camera source =
        from_downscaled ? RescaleCamera(camera, rgb.cols, rgb.rows) : camera;
    const Camera pinhole = from_downscaled
                               ? PinholeOf(target, camera.camera_id)
                               : pinhole_cameras_.at(camera.camera_id);
    rgb = WarpImage(rgb, *loader_->Map(source, pinhole));
  }
  const cv::Size target_size(target.width, target.height);
  if (rgb.size() != target_size) {
    cv::resize(rgb, rgb, target_size, 0, 0, cv::INTER_AREA);
  }
  ImageRGB result = ToImageRGB(rgb);
  loader_->Insert(view, result);
  return result;
}

bool Workspace::HeldOut(size_t view) const {
  return listed_test_.empty() ? view % 8 == 0 : bool(listed_test_[view]);
}

std::vector<size_t> Workspace::TrainViews(bool eval) const {
  std::vector<size_t> views;
  for (size_t i = 0; i < views_.size(); ++i) {
    if (!eval || !HeldOut(i)) views.push_back(i);
  }
  return views;
}

std::vector<size_t> Workspace::TestViews(bool eval) const {
  std::vector<size_t> views;
  for (size_t i = 0; eval && i < views_.size(); ++i) {
    if (HeldOut(i)) views.push_back(i);
  }
  return views;
}

void Workspace::PointCloud(std::vector<float>* xyz,
                           std::vector<float>* rgb) const {
  std::vector<point3D_t> ids;
  ids.reserve(reconstruction_.NumPoints3D());
  for (const auto& [id, point] : reconstruction_.Points3D()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());
  xyz->clear();
  rgb->clear();
  xyz->reserve(3 * ids.size());
  rgb->reserve(3 * ids.size());
  for (const point3D_t id : ids) {
    const Point3D& point = reconstruction_.GetPoint3D(id);
    for (int k = 0; k < 3; ++k) {
      xyz->push_back(static_cast<float>(point.xyz(k)));
      rgb->push_back(point.rgb(k) / 255.f);
    }
  }
}

double Workspace::SceneExtent() const {
  if (views_.empty()) return 0.0;
  std::vector<Eigen::Vector3d> centers;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t view = 0; view < views_.size(); ++view) {
    centers.push_back(ViewImage(view).ProjectionCenter());
    mean += centers.back();
  }
  mean /= double(centers.size());
  double max_distance = 0;
  for (const auto& center : centers) {
    max_distance = std::max(max_distance, (center - mean).norm());
  }
  return 1.1 * max_distance;
}

}  // namespace watergs
