// Poses for images that come without one (screenshots, video frames, copies
// of renders): each image is registered to a workspace's reconstruction, so
// that the owner can render the raw model at the same viewpoint and read the
// watermark from the difference (`detect --raw_path`). The index holds SIFT
// features of the workspace's photos that lie on a projected SfM point (so
// each carries a 3D position); a query's features are matched to it (Lowe's
// ratio test), the pose found by PnP RANSAC with the workspace camera's
// intrinsics scaled to the query's width, then focal length and principal
// point refined on the inliers (a crop moves the principal point, a resize
// the focal length). OpenCV does the features, matching and geometry.
//
// Building the index is the slow part (SIFT on every photo and render):
// Save writes it to a file and Load reads it back, so that `detect` indexes
// a workspace once (its cache, WS/detect_index/) and each later call only
// registers.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/image.h"
#include "gaussian/trainer.h"
#include "plugin/workspace.h"

namespace watergs {

struct RegistrationOptions {
  // Lowe's ratio: best match distance below this fraction of the second's.
  double ratio = 0.85;
  // RANSAC inlier threshold, pixels of the query.
  double inlier_px = 3.0;
  // Fewer inliers than this: not registered.
  int min_inliers = 15;
  // Alternatives (Registration::alternatives): at most this many, each with
  // at least alternative_inliers inliers.
  int max_alternatives = 3;
  int alternative_inliers = 6;
  // A photo's feature takes an SfM point's 3D position when within this
  // many pixels of the point's projection.
  double associate_px = 2.5;
  // Views left out of the index (a test registers a photo against the
  // others).
  std::vector<size_t> skip_views;
};

// The outcome for one image.
struct Registration {
  bool registered = false;
  // The pinhole camera of the image (its size, refined intrinsics).
  RenderCamera camera;
  // The pose solved at the guessed intrinsics (the workspace camera's,
  // centred on the image, scaled for a resize) before they were refined: a
  // second start for a photometric refinement.
  RenderCamera guessed_camera;
  // Other poses the matches support (at the guessed intrinsics), from
  // RANSAC on the matches the poses before left out, most inliers first:
  // on repetitive texture the most supported pose can be a period off, and
  // a photometric comparison tells them apart.
  std::vector<RenderCamera> alternatives;
  // Ratio-test matches, RANSAC inliers, inlier RMS reprojection (pixels).
  int matches = 0, inliers = 0;
  double rms_px = 0;
  // Median depth of the inliers' SfM points in front of the camera (world
  // units): the scale a pose refinement moves at.
  double depth = 0;
  // Why not registered (one line), empty when registered.
  std::string why;
};

class ImageRegistrar {
 public:
  // Builds the index from the views of `workspace` (photos loaded through
  // `views`; the index keeps what it needs). Error if no photo has a
  // feature on an SfM point.
  ImageRegistrar(const Workspace& workspace, const TrainingViews& views,
                 const RegistrationOptions& options = {});
  // An empty index (AddRenders fills it); queries start from `reference`'s
  // intrinsics.
  explicit ImageRegistrar(const RenderCamera& reference,
                          const RegistrationOptions& options = {});
  ~ImageRegistrar();
  ImageRegistrar(ImageRegistrar&&) noexcept;
  ImageRegistrar& operator=(ImageRegistrar&&) noexcept;

  // Writes the index to `path` atomically (AtomicWriteFile): the magic
  // "WGSIDX1", a format version, the counts, the reference camera, every
  // feature's descriptor (8 bits a value when all are SIFT's integers in
  // [0, 255], as OpenCV's are, else 32-bit floats) and 3D point, then the
  // FNV-1a 64 checksum of all that; little-endian. Throws Error
  // ("<path>: ...") if it cannot be written.
  void Save(const std::string& path) const;
  // The registrar `Save` wrote to `path`, answering queries with `options`
  // (those that shaped the index, associate_px and skip_views, are the
  // saved registrar's). It registers every image exactly as the registrar
  // saved did. A file missing, truncated, of another format or version, or
  // whose checksum does not match throws Error("<path>: <problem>").
  static ImageRegistrar Load(const std::string& path,
                             const RegistrationOptions& options = {});

  // Adds to the index the features of renders of the raw model at `cameras`
  // (viewpoints no photo was taken from), each lifted to 3D through the
  // render's depth (RenderDepth): an image taken far from every photo finds
  // a render near it.
  using RenderFunction = std::function<ImageRGB(const RenderCamera&)>;
  using DepthFunction = std::function<std::vector<float>(const RenderCamera&)>;
  void AddRenders(const std::vector<RenderCamera>& cameras,
                  const RenderFunction& render, const DepthFunction& depth);

  Registration Register(const ImageRGB& image) const;
  // SfM-anchored features in the index.
  size_t IndexSize() const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;
  RegistrationOptions options_;
  // The first view's camera: the intrinsics a query starts from.
  RenderCamera reference_;
};

}  // namespace watergs
