// From a folder of photos to a COLMAP workspace, with COLMAP's own binary:
// feature extraction, matching and mapping, with settings chosen for the
// photo count and the machine, progress with an ETA per stage, and resume
// from the first stage not finished. The result is the layout every watergs
// command reads: <workspace>/images (the photos), <workspace>/sparse/0 (the
// largest model the mapper wrote), <workspace>/database.db.
#pragma once

#include <string>
#include <vector>

#include "plugin/photo_cameras.h"

namespace watergs {

// Settings a run uses, and why (printed, and in docs/reconstruct.md).
struct ColmapPlan {
  // SIFT features an image (SiftExtraction.max_num_features).
  int max_features = 2048;
  // "exhaustive" or "sequential".
  std::string matcher = "exhaustive";
  // Threads for every stage.
  int num_threads = 2;
  // SIFT on the GPU (a CUDA-built colmap and a visible GPU).
  bool use_gpu = false;
  // Matching in watergs (exact nearest neighbours, sift_matching.h), then
  // COLMAP's geometric verification (matches_importer); else COLMAP's own
  // matcher. On the CPU, unless a photo's name holds a space (COLMAP's match
  // list cannot name it).
  bool exact_matching = false;
  // One camera for all photos (in capture order, one size, at most one EXIF
  // camera); else COLMAP extracts a camera per photo and reconstruct shares
  // one among the photos of each EXIF camera and size (photo_cameras.h).
  bool single_camera = true;
  bool camera_per_photo = false;
  // One line per choice: "matcher exhaustive: 48 photos, 1,128 pairs".
  std::vector<std::string> reasons;
};

// Most photos named in capture order matched exhaustively (by default) (4,950
// pairs, ~2.5 min at 2,048 features on 2 cores with the exact matcher). Every
// pair is what places photos right on repetitive texture: sequential matching
// (with COLMAP's quadratic overlap) joined two groups of the demo's 48 photos
// in a wrong relative pose at 0.29 px reprojection error.
inline constexpr int kMaxExhaustivePhotos = 100;

struct ReconstructOptions {
  std::string image_path, workspace_path;
  // The COLMAP binary (a name on PATH or a path).
  std::string colmap = "colmap";
  // 0: chosen by PlanReconstruction.
  int max_features = 0;
  // "auto", "exhaustive" or "sequential".
  std::string matcher = "auto";
  // "auto": photos named in capture order (one numbered sequence) are
  // matched exhaustively up to this many, sequentially beyond; photos in no
  // order always exhaustively.
  int sequential_above = kMaxExhaustivePhotos;
  // 0: all cores.
  int num_threads = 0;
  // Fewest registered photos accepted, as a fraction of the photos.
  double min_registered_fraction = 0.5;
};

// The photo files of `image_path` (.jpg/.jpeg/.png, any case, sorted).
std::vector<std::string> ListPhotos(const std::string& image_path);

// Whether the photos' names are one numbered sequence (one prefix without
// digits, then a number or a timestamp, each once: IMG_0001.JPG,
// frame_00042.png, DJI_20200223_163016_842.jpg), as a camera names a walk or
// a video; a web collection or a mix of captures is not.
bool NamedInCaptureOrder(const std::vector<std::string>& photos);

// COLMAP's SequentialMatching.overlap (sift_matching.h: SequentialPairs).
inline constexpr int kSequentialOverlap = 10;

// Settings for `num_photos` photos on `num_threads` threads: photos in
// capture order (`in_capture_order`) are matched exhaustively up to
// options.sequential_above, sequentially beyond; photos in no order are
// matched exhaustively (with the time it should take). `cameras` (from
// GroupPhotosByCamera) says which photos share a camera. 2,048 features an
// image on the CPU (8,192 with GPU SIFT), matched exactly by watergs on the
// CPU unless `names_with_spaces`; options given override the choice.
ColmapPlan PlanReconstruction(int num_photos, int num_threads, bool gpu_sift,
                              const PhotoCameras& cameras,
                              const ReconstructOptions& options,
                              bool names_with_spaces = false,
                              bool in_capture_order = true);

// Held-out views this far below the best one suggest misplaced photos.
inline constexpr double kOutlierViewDb = 6;

// A warning line (empty when none) naming the held-out views of train's
// report.json text that read kOutlierViewDb or more below the best: what
// photos joined in a wrong pose look like (the demo's sequentially matched
// model read 14-16 dB on them, 23-24 dB on the rest), though a scene can vary
// that much too.
std::string OutlierViewWarning(const std::string& train_report_json);

// Runs the stages not yet done (markers in <workspace>/.reconstruct/), then
// keeps the largest model as sparse/0. Error (one line) for a missing colmap
// binary, fewer than 3 readable photos, a stage that fails (its log named)
// or a model that registers too few photos.
void RunReconstruction(const ReconstructOptions& options);

}  // namespace watergs
