// LLFF's poses_bounds.npy (the NeRF datasets' camera file) read as a COLMAP
// reconstruction, so that a model of the same photos can be compared with it
// (`model_info --reference_path poses_bounds.npy`, pose_comparison.h).
#pragma once

#include <string>
#include <vector>

#include "plugin/reconstruction.h"

namespace watergs {

// An N x 17 float64 array, one row per photo in file-name order: a 3 x 5
// matrix row by row, whose columns are the camera-to-world axes down, right
// and backwards (LLFF's convention), the camera centre, and (height, width,
// focal length) in pixels of the full photo; then the near and far depth
// bounds. Row i becomes image_names[i] (the photos LLFF's imgs2poses saw,
// sorted), with a PINHOLE camera per distinct (height, width, focal) and
// COLMAP's world-to-camera pose; no 3D points. Throws Error naming `path`
// for anything else (not .npy, another dtype or shape, a count unlike
// image_names', a non-finite value).
Reconstruction ReadPosesBounds(const std::string& path,
                               const std::vector<std::string>& image_names);

// The photo names of the LLFF scene holding `path`: the image files in the
// images/ folder beside it, sorted (LLFF orders its rows so).
std::vector<std::string> PosesBoundsImageNames(const std::string& path);

}  // namespace watergs
