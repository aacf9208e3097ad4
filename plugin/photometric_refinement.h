// Photometric refinement of a registered camera: the owner's reading
// subtracts the raw model's render at the camera a screenshot was registered
// to, so the render must sit on the image to a small fraction of a pixel.
// Feature registration (plugin/image_registration.h) gets within a few
// tenths of a pixel; this step moves the pose, focal length and principal
// point to where the blurred render matches the blurred image best in least
// squares (Ceres' Levenberg-Marquardt), the direct alignment of photometric
// SLAM and bundle adjustment. The Jacobian is the blurred render's image
// gradient times each parameter's image motion (one render a solver step)
// where the raw model's depth is given, else finite differences over renders
// (one render per parameter a step).
#pragma once

#include <functional>
#include <vector>

#include "gaussian/camera.h"
#include "gaussian/image.h"

namespace watergs {

// Renders the raw model at a camera (RGB in [0, 1], the camera's size).
using CameraRenderer = std::function<ImageRGB(const RenderCamera&)>;

// The raw model's z-depth at a camera (H x W, world units; NaN or <= 0 where
// it leaves a pixel uncovered).
using DepthRenderer = std::function<std::vector<float>(const RenderCamera&)>;

struct PhotometricOptions {
  // Gaussian blur (pixels) of both images before comparing: widens the basin
  // and keeps the watermark and JPEG noise out of the fit.
  double blur_sigma = 1.0;
  // Finite-difference step (without depth_map), pixels of motion at the
  // image.
  double step_px = 0.25;
  int max_iterations = 10;
  // A move larger than this from the start it left (pixels at a corner, at
  // the scene's median depth) is a wrong basin: kept out. Feature registrations
  // of the demo's JPEG screenshots needed up to 9 (a zoom moves corners most).
  double max_move_px = 20.0;
  // After the pose, also the focal length and principal point, kept only
  // when they lower the residual RMS by this fraction more: at the true
  // intrinsics their 3 extra degrees of freedom fit noise (0.3-1.5% lower on
  // the demo's free views, the pose 0.05-0.43 px off instead of 0.03-0.25).
  bool refine_intrinsics = true;
  double intrinsics_gain = 0.03;
  // Given: the Jacobian from the image gradient and the depth (rendered once
  // per start, read at the moved camera as it was: the moves are pixels);
  // empty: finite differences over renders, 7-10 renders a Jacobian instead
  // of one (about half to a third of the renders over a whole refinement:
  // docs/history.md, "detect's cost").
  DepthRenderer depth_map;
};

struct PhotometricResult {
  bool applied = false;  // the refined camera was kept
  RenderCamera camera;   // the refined camera, or the input one
  // RMS of the blurred RGB difference before and after.
  double rms_before = 0, rms_after = 0;
  // Largest motion of the image's corners and centre between the camera
  // kept and the start it was aligned from (pixels at `depth`).
  double moved_px = 0;
  // That start's index in `starts`.
  int start = 0;
  int renders = 0;
};

// image: H x W RGB; starts: its registered camera first, then other guesses
// (the same size; e.g. the pose with the workspace's intrinsics), each
// aligned by its pose alone before the best is aligned in full; depth: a
// typical depth of the scene in front of it (world units), which scales the
// translation's steps. Never fails: when nothing better than starts[0] is
// found, starts[0] comes back with applied = false.
PhotometricResult RefinePhotometrically(const ImageRGB& image,
                                        const std::vector<RenderCamera>& starts,
                                        double depth,
                                        const CameraRenderer& render,
                                        const PhotometricOptions& options = {});

// The camera moved by `delta` (9 numbers): rotation (3, radians times fx),
// translation in the camera frame (3, world units times fx / depth), focal
// length scale (pixels at the image's edge), principal point (2, pixels).
// Exposed for the test of its units.
RenderCamera MoveCamera(const RenderCamera& camera, double depth,
                        const double* delta);

// H x W x 3 floats of `image`, blurred by `sigma` pixels (none at 0): what
// the photometric fits compare.
std::vector<float> Blurred(const ImageRGB& image, double sigma);

// The Jacobian of the blurred render at MoveCamera(camera, depth, x) with
// respect to the first `free` entries of x, from the image gradient of
// `blurred` (H x W x 3, rendered there) and the raw model's z-depth at
// `camera` (H x W; uncovered pixels take `depth`; read at the moved camera as
// it was, which only the translation's columns feel): row-major, one row per
// value of `blurred`. Throws std::invalid_argument on other sizes. Exposed
// for the test against finite differences.
std::vector<double> GradientJacobian(const std::vector<float>& blurred,
                                     const std::vector<float>& depth_map,
                                     const RenderCamera& camera, double depth,
                                     const double* x, int free);

// Largest distance (pixels) between where `a` and `b` put the points at
// `depth` behind the image's corners and centre, as seen by `a`.
double CameraMotionPx(const RenderCamera& a, const RenderCamera& b,
                      double depth);

}  // namespace watergs
