// 3D distortion layers N(Θ) of WATER-GS (paper, "3D distortion layers"):
// Identity, Gaussian noise on positions, Dropout and Crop of the point set.
// During fine-tuning one layer is sampled per iteration and the renderer sees
// N(Θ); gradients flow back to the surviving Gaussians through `source`.
// The same layers distort files in `watergs attack`.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"

namespace watergs {

enum class DistortionKind { kIdentity, kGaussianNoise, kDropout, kCrop };

// One configured layer: its kind, strength and sampling weight.
struct DistortionSpec {
  // Which distortion.
  DistortionKind kind = DistortionKind::kIdentity;
  // GN: sigma of the position noise in scene units; Dropout/Crop: fraction p
  // of Gaussians removed; unused for Identity.
  double strength = 0.0;
  // Relative probability of being sampled in a fine-tuning iteration.
  double weight = 1.0;
};

// Parses "identity", "gn:0.01", "dropout:0.1", "crop:0.1", optionally with a
// weight "gn:0.01@2"; throws Error naming the text on anything else.
DistortionSpec ParseDistortionSpec(const std::string& text);
// Parses a comma-separated list of specs; throws Error if empty.
std::vector<DistortionSpec> ParseDistortionList(const std::string& text);
// "gn:0.01" etc.; the inverse of ParseDistortionSpec (weight omitted).
std::string ToString(const DistortionSpec& spec);

class DistortionLayer {
 public:
  virtual ~DistortionLayer() = default;
  // True if Apply would return the input unchanged; callers then render the
  // input directly and skip the copy and the gradient scatter.
  virtual bool IsIdentity() const { return false; }
  // out = N(in). source[i] is the index in `in` of output Gaussian i.
  // `out` must not alias `in`.
  virtual void Apply(const GaussianModel& in, std::mt19937_64& rng,
                     GaussianModel* out,
                     std::vector<uint32_t>* source) const = 0;
  // The spec this layer was built from.
  virtual DistortionSpec spec() const = 0;
};

// Builds the layer for one spec; throws Error for strengths out of range
// (sigma < 0, p outside [0, 1)).
std::unique_ptr<DistortionLayer> MakeDistortionLayer(
    const DistortionSpec& spec);

// Gradients w.r.t. N(Θ) (shape of the distorted model) -> gradients w.r.t. Θ
// (n_in Gaussians): rows are added to their source row, removed Gaussians get
// zero. Additive position noise has identity Jacobian, so every layer's
// backward is this scatter.
void ScatterGradients(const GaussianGradients& distorted,
                      const std::vector<uint32_t>& source, size_t n_in,
                      int rest_stride, GaussianGradients* grads);

// Samples one layer per fine-tuning iteration with probability proportional
// to its weight. Only the configured layers are ever built.
class DistortionSampler {
 public:
  explicit DistortionSampler(const std::vector<DistortionSpec>& specs);
  // The layer for this iteration.
  const DistortionLayer& Sample(std::mt19937_64& rng) const;
  // True if every configured layer is the identity (no copies, no scatter).
  bool IdentityOnly() const;
  size_t size() const { return layers_.size(); }

 private:
  std::vector<std::unique_ptr<DistortionLayer>> layers_;
  std::vector<double> cumulative_weights_;
};

}  // namespace watergs
