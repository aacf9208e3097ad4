// The 3D Gaussian Splatting model: one struct of float32 arrays, N Gaussians.
// Knows nothing of files or cameras; PLY I/O lives in ply_io.h.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <string>
#include <vector>

namespace watergs {

// Number of SH coefficients per channel for a degree (1, 4, 9, 16).
constexpr int NumShCoeffs(int degree) { return (degree + 1) * (degree + 1); }

// Parameter groups, in the order the optimiser and masks name them.
enum class ParamGroup { kXyz, kFDc, kFRest, kOpacity, kScaling, kRotation };

struct GaussianModel {
  // Highest SH degree stored (0-3); sets the width of sh_rest.
  int sh_degree = 3;
  // Means in world coordinates, N x 3 (x, y, z).
  std::vector<float> means;
  // Log of the per-axis standard deviations, N x 3.
  std::vector<float> log_scales;
  // Rotation quaternions, N x 4, w first; need not be normalised.
  std::vector<float> quats;
  // Opacity before the sigmoid, N.
  std::vector<float> opacity_logits;
  // SH degree-0 coefficients, N x 3 (r, g, b).
  std::vector<float> sh_dc;
  // Higher SH coefficients, N x (NumShCoeffs(sh_degree) - 1) x 3: coefficient
  // major, rgb interleaved (Inria's in-memory `features_rest` layout).
  std::vector<float> sh_rest;

  // Number of Gaussians.
  size_t size() const { return opacity_logits.size(); }
  // Floats of sh_rest per Gaussian: 3 * (NumShCoeffs(sh_degree) - 1).
  int sh_rest_stride() const { return 3 * (NumShCoeffs(sh_degree) - 1); }
  // Resizes every array to n Gaussians (new entries zeroed).
  void Resize(size_t n);
  // Number of non-finite floats over all arrays.
  size_t CountNonFinite() const;
  // Keeps the Gaussians whose keep[i] is true, in order.
  void Filter(const std::vector<bool>& keep);
  // Appends Gaussian i of `other` (same sh_degree) to this model.
  void AppendFrom(const GaussianModel& other, size_t i);
};

// Values a file may legitimately hold that are not finite: an opacity logit
// of +-Inf (alpha exactly 1 or 0, what an 8-bit alpha of 255 or 0 decodes to)
// and a log-scale of -Inf (a scale of 0, a flat Gaussian). Readers replace
// them by what viewers render: logits +-kOpacityLogitLimit and log-scale
// kLogScaleFloor. sigmoid(20) rounds to 1.0f and sigmoid(-20) = 2e-9 is far
// below the 1/255 alpha under which rasterizers skip a Gaussian; exp(20) =
// 4.9e8 and its square stay finite in float, so losses and gradients of a
// model read this way stay finite; 20 is also far beyond the largest logit
// an 8-bit alpha can state (logit(254/255) = 5.5). exp(-20) = 2e-9 scene
// units is zero thickness at any scene scale.
constexpr float kOpacityLogitLimit = 20.f;
constexpr float kLogScaleFloor = -20.f;

// Opacity logit of an alpha in [0, 1], clamped to +-kOpacityLogitLimit
// (alpha 0 and 1 give -20 and +20, NaN gives NaN).
float AlphaToOpacityLogit(double alpha);
// sigmoid(logit).
double OpacityLogitToAlpha(float logit);

// The one warning line readers print when they replaced `count` infinite
// values of `path` (see kOpacityLogitLimit); nothing if count is 0 or `out`
// is null.
void WarnInfinitiesReplaced(const std::string& path, size_t count,
                            std::ostream* out);

// SH DC coefficient for a colour in [0, 1]: (c - 0.5) / C0 (Inria's RGB2SH).
float RgbToShDc(float rgb);
// Inverse of RgbToShDc.
float ShDcToRgb(float dc);

}  // namespace watergs
