#include "distortion/distortion_layer.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/text_util.h"

namespace watergs {
namespace {

// Copies the Gaussians whose keep[i] is set, recording their source index.
void CopyKept(const GaussianModel& in, const std::vector<bool>& keep,
              GaussianModel* out, std::vector<uint32_t>* source) {
  *out = in;
  out->Filter(keep);
  source->clear();
  source->reserve(out->size());
  for (size_t i = 0; i < keep.size(); ++i) {
    if (keep[i]) source->push_back(static_cast<uint32_t>(i));
  }
}

void IdentitySource(size_t n, std::vector<uint32_t>* source) {
  source->resize(n);
  for (size_t i = 0; i < n; ++i) (*source)[i] = static_cast<uint32_t>(i);
}

size_t RemovedCount(size_t n, double fraction) {
  return std::min(n, static_cast<size_t>(std::llround(fraction * n)));
}

class IdentityLayer : public DistortionLayer {
 public:
  bool IsIdentity() const override { return true; }
  void Apply(const GaussianModel& in, std::mt19937_64&, GaussianModel* out,
             std::vector<uint32_t>* source) const override {
    *out = in;
    IdentitySource(in.size(), source);
  }
  DistortionSpec spec() const override { return {}; }
};

// Adds N(0, sigma^2) to every coordinate of every mean.
class GaussianNoiseLayer : public DistortionLayer {
 public:
  explicit GaussianNoiseLayer(DistortionSpec spec) : spec_(spec) {}
  void Apply(const GaussianModel& in, std::mt19937_64& rng, GaussianModel* out,
             std::vector<uint32_t>* source) const override {
    *out = in;
    std::normal_distribution<float> noise(0.f,
                                          static_cast<float>(spec_.strength));
    for (float& x : out->means) x += noise(rng);
    IdentitySource(in.size(), source);
  }
  DistortionSpec spec() const override { return spec_; }

 private:
  DistortionSpec spec_;
};

// Removes exactly round(p * N) Gaussians chosen uniformly, keeping file order
// (selection sampling: each index is kept with probability
// still_to_keep / still_to_visit).
class DropoutLayer : public DistortionLayer {
 public:
  explicit DropoutLayer(DistortionSpec spec) : spec_(spec) {}
  void Apply(const GaussianModel& in, std::mt19937_64& rng, GaussianModel* out,
             std::vector<uint32_t>* source) const override {
    const size_t n = in.size();
    size_t to_keep = n - RemovedCount(n, spec_.strength);
    std::vector<bool> keep(n, false);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    for (size_t i = 0; i < n && to_keep > 0; ++i) {
      if (uniform(rng) * double(n - i) < double(to_keep)) {
        keep[i] = true;
        --to_keep;
      }
    }
    CopyKept(in, keep, out, source);
  }
  DistortionSpec spec() const override { return spec_; }

 private:
  DistortionSpec spec_;
};

// Removes one contiguous run of round(p * N) Gaussians in file order, at a
// uniformly random start.
class CropLayer : public DistortionLayer {
 public:
  explicit CropLayer(DistortionSpec spec) : spec_(spec) {}
  void Apply(const GaussianModel& in, std::mt19937_64& rng, GaussianModel* out,
             std::vector<uint32_t>* source) const override {
    const size_t n = in.size();
    const size_t removed = RemovedCount(n, spec_.strength);
    std::uniform_int_distribution<size_t> start_dist(0, n - removed);
    const size_t start = start_dist(rng);
    std::vector<bool> keep(n, true);
    for (size_t i = start; i < start + removed; ++i) keep[i] = false;
    CopyKept(in, keep, out, source);
  }
  DistortionSpec spec() const override { return spec_; }

 private:
  DistortionSpec spec_;
};

void ScatterRows(const std::vector<float>& from,
                 const std::vector<uint32_t>& source, int stride,
                 std::vector<float>* to) {
  for (size_t i = 0; i < source.size(); ++i) {
    const float* src = &from[i * stride];
    float* dst = &(*to)[size_t(source[i]) * stride];
    for (int k = 0; k < stride; ++k) dst[k] += src[k];
  }
}

}  // namespace

DistortionSpec ParseDistortionSpec(const std::string& text) {
  DistortionSpec spec;
  std::string body = text;
  const size_t at = body.find('@');
  try {
    if (at != std::string::npos) {
      const std::optional<double> weight =
          ParseFiniteDouble(body.substr(at + 1));
      if (!weight || !(*weight > 0)) throw std::invalid_argument("weight");
      spec.weight = *weight;
      body = body.substr(0, at);
    }
    const size_t colon = body.find(':');
    const std::string name = body.substr(0, colon);
    if (name == "identity" && colon == std::string::npos) {
      spec.kind = DistortionKind::kIdentity;
      return spec;
    }
    if (colon == std::string::npos) throw std::invalid_argument("strength");
    const std::optional<double> strength =
        ParseFiniteDouble(body.substr(colon + 1));
    if (!strength) throw std::invalid_argument("strength");
    spec.strength = *strength;
    if (name == "gn") {
      spec.kind = DistortionKind::kGaussianNoise;
    } else if (name == "dropout") {
      spec.kind = DistortionKind::kDropout;
    } else if (name == "crop") {
      spec.kind = DistortionKind::kCrop;
    } else {
      throw std::invalid_argument("name");
    }
  } catch (const std::logic_error&) {
    Fail("distortion `" + Printable(text) +
         "`: expected identity, gn:SIGMA, dropout:P or crop:P, optionally "
         "followed by @WEIGHT");
  }
  MakeDistortionLayer(spec);  // Validates the strength.
  return spec;
}

std::vector<DistortionSpec> ParseDistortionList(const std::string& text) {
  std::vector<DistortionSpec> specs;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) specs.push_back(ParseDistortionSpec(item));
  }
  if (specs.empty()) Fail("distortion list `" + Printable(text) + "` is empty");
  return specs;
}

std::string ToString(const DistortionSpec& spec) {
  std::ostringstream out;
  switch (spec.kind) {
    case DistortionKind::kIdentity:
      return "identity";
    case DistortionKind::kGaussianNoise:
      out << "gn:";
      break;
    case DistortionKind::kDropout:
      out << "dropout:";
      break;
    case DistortionKind::kCrop:
      out << "crop:";
      break;
  }
  out << spec.strength;
  return out.str();
}

std::unique_ptr<DistortionLayer> MakeDistortionLayer(
    const DistortionSpec& spec) {
  switch (spec.kind) {
    case DistortionKind::kIdentity:
      return std::make_unique<IdentityLayer>();
    case DistortionKind::kGaussianNoise:
      if (!(spec.strength >= 0)) {
        Fail("distortion " + ToString(spec) + ": sigma must be >= 0");
      }
      return std::make_unique<GaussianNoiseLayer>(spec);
    case DistortionKind::kDropout:
    case DistortionKind::kCrop:
      if (!(spec.strength >= 0 && spec.strength < 1)) {
        Fail("distortion " + ToString(spec) + ": fraction must be in [0, 1)");
      }
      if (spec.kind == DistortionKind::kDropout) {
        return std::make_unique<DropoutLayer>(spec);
      }
      return std::make_unique<CropLayer>(spec);
  }
  Fail("unknown distortion kind");
}

void ScatterGradients(const GaussianGradients& distorted,
                      const std::vector<uint32_t>& source, size_t n_in,
                      int rest_stride, GaussianGradients* grads) {
  grads->Reset(n_in, rest_stride);
  ScatterRows(distorted.means, source, 3, &grads->means);
  ScatterRows(distorted.log_scales, source, 3, &grads->log_scales);
  ScatterRows(distorted.quats, source, 4, &grads->quats);
  ScatterRows(distorted.opacity_logits, source, 1, &grads->opacity_logits);
  ScatterRows(distorted.sh_dc, source, 3, &grads->sh_dc);
  if (rest_stride > 0) {
    ScatterRows(distorted.sh_rest, source, rest_stride, &grads->sh_rest);
  }
  ScatterRows(distorted.mean2d_grad_norm, source, 1, &grads->mean2d_grad_norm);
  ScatterRows(distorted.mean2d_grad_norm_ndc, source, 1,
              &grads->mean2d_grad_norm_ndc);
  for (size_t i = 0; i < source.size(); ++i) {
    grads->visible[source[i]] |= distorted.visible[i];
  }
}

DistortionSampler::DistortionSampler(const std::vector<DistortionSpec>& specs) {
  if (specs.empty()) Fail("no distortion layers configured");
  double total = 0;
  for (const auto& spec : specs) {
    layers_.push_back(MakeDistortionLayer(spec));
    total += spec.weight;
    cumulative_weights_.push_back(total);
  }
}

const DistortionLayer& DistortionSampler::Sample(std::mt19937_64& rng) const {
  if (layers_.size() == 1) return *layers_[0];
  std::uniform_real_distribution<double> uniform(0.0,
                                                 cumulative_weights_.back());
  const double u = uniform(rng);
  const size_t i = std::upper_bound(cumulative_weights_.begin(),
                                    cumulative_weights_.end(), u) -
                   cumulative_weights_.begin();
  return *layers_[std::min(i, layers_.size() - 1)];
}

bool DistortionSampler::IdentityOnly() const {
  for (const auto& layer : layers_) {
    if (!layer->IsIdentity()) return false;
  }
  return true;
}

}  // namespace watergs
