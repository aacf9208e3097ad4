// A COLMAP workspace opened for training: the sparse model, the registered
// views sorted by name, their pinhole render cameras (undistorted when the
// COLMAP camera has distortion, scaled by `downscale`), on-demand image
// loading with a bounded LRU cache, the held-out split and the SfM points.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/image.h"
#include "plugin/reconstruction.h"

namespace watergs {

struct WorkspaceOptions {
  // COLMAP workspace: holds images/ and sparse/0 (or sparse/).
  std::string workspace_path;
  // Sparse model folder; default <workspace>/sparse/0, else <workspace>/sparse.
  std::string input_path;
  // Image folder; default <workspace>/images, where <workspace> is, if not
  // given, the folder holding the model's sparse/ (or the model's parent).
  std::string image_path;
  // Whether the image folder may be missing, for commands that only render
  // the cameras or can do without ground truth: has_images() then tells,
  // and a view's image is read only when asked for. A folder that exists is
  // checked as always.
  bool images_optional = false;
  // 1, 2, 4, 8: use <image_path>_<k> (e.g. <workspace>/images_4) if it
  // exists, else resize on load (INTER_AREA).
  int downscale = 1;
  // Distorted cameras: `colmap image_undistorter` instead of OpenCV.
  bool use_colmap_undistorter = false;
  // Bounded decoded-image cache.
  size_t image_cache_bytes = size_t(1) << 30;
  // Where `colmap image_undistorter` writes (reused if it already holds a
  // model); default <workspace>/undistorted_watergs.
  std::string undistorted_path;
};

class ImageLoader;

class Workspace {
 public:
  // Reads the model (bin or txt), scales the intrinsics of cameras whose
  // photos were all resized at the camera's aspect ratio, checks images exist
  // and sizes match cameras; throws Error.
  static Workspace Open(const WorkspaceOptions& options);
  Workspace(Workspace&&) noexcept;
  Workspace& operator=(Workspace&&) noexcept;
  ~Workspace();

  const Reconstruction& reconstruction() const { return reconstruction_; }
  // Registered images sorted by name; "view i" means the i-th of these.
  size_t NumViews() const { return views_.size(); }
  const std::string& ViewName(size_t view) const;
  // The COLMAP image of view i.
  const Image& ViewImage(size_t view) const;
  // Pinhole camera for rendering view i (undistorted intrinsics if the camera
  // had distortion; scaled by downscale).
  RenderCamera ViewCamera(size_t view) const;
  // The (undistorted, downscaled) image, float RGB in [0,1]; cached (LRU,
  // bounded).
  ImageRGB LoadView(size_t view) const;
  // With eval, the views named in <workspace>/test_views.txt (one image name
  // a line, as transforms_importer writes a scene's own test split) are held
  // out; without that file, LLFF's and Mip-NeRF 360's convention: every 8th
  // view (i % 8 == 0).
  std::vector<size_t> TrainViews(bool eval) const;
  std::vector<size_t> TestViews(bool eval) const;
  // Whether view i is held out under eval (the split file's, or i % 8 == 0).
  bool HeldOut(size_t view) const;
  // SfM points: xyz (N x 3) and rgb in [0,1] (N x 3), for initialisation.
  void PointCloud(std::vector<float>* xyz, std::vector<float>* rgb) const;
  // Inria's cameras_extent: 1.1 * max distance of camera centres from their
  // mean.
  double SceneExtent() const;

  // The options with every default path filled in.
  const WorkspaceOptions& options() const { return options_; }
  // Folder the model was read from.
  const std::string& model_path() const { return model_path_; }
  // Whether any camera had distortion (and is rendered through an
  // undistorted pinhole camera).
  bool undistorted() const { return undistorted_; }
  // The split file read at Open (empty: every 8th view is held out).
  const std::string& test_views_path() const { return test_views_path_; }
  // Whether the image folder exists (always, unless images_optional).
  bool has_images() const { return has_images_; }
  // One line per camera whose intrinsics were scaled to its photos (photos
  // resized at the camera's aspect ratio); also printed to stderr at Open.
  const std::vector<std::string>& notices() const { return notices_; }

 private:
  Workspace() = default;
  static void ReadTestViews(Workspace* workspace,
                            const WorkspaceOptions& given);

  WorkspaceOptions options_;
  std::string model_path_;
  Reconstruction reconstruction_;
  // Registered image ids sorted by image name.
  std::vector<image_t> views_;
  // Render cameras per view, computed at Open.
  std::vector<RenderCamera> view_cameras_;
  // Per camera id: the pinhole camera it is rendered with (full size).
  std::map<camera_t, Camera> pinhole_cameras_;
  bool undistorted_ = false;
  bool has_images_ = false;
  // Per view: held out by the split file (empty without one).
  std::vector<bool> listed_test_;
  std::string test_views_path_;
  std::vector<std::string> notices_;
  std::unique_ptr<ImageLoader> loader_;
};

}  // namespace watergs
