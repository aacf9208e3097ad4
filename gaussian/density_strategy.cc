// Inria's adaptive density control (densify_and_prune, reset_opacity) behind
// the DensityStrategy interface.
#include "gaussian/density_strategy.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr ParamGroup kAllGroups[] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

float Sigmoid(float x) { return 1.f / (1.f + std::exp(-x)); }

// Largest of a Gaussian's three world-space standard deviations.
float MaxScale(const GaussianModel& model, size_t i) {
  const float* s = &model.log_scales[3 * i];
  return std::exp(std::max({s[0], s[1], s[2]}));
}

// Rotation (row-major) of a normalised quaternion (w, x, y, z); zero -> I.
void Rotation(const float* q, double* R) {
  double w = q[0], x = q[1], y = q[2], z = q[3];
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (!(n > 1e-12) || !std::isfinite(n)) {
    w = 1, x = y = z = 0;
  } else {
    w /= n, x /= n, y /= n, z /= n;
  }
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
}

// model <- the Gaussians parent[0], parent[1], ... of model.
void GatherModel(const std::vector<int64_t>& parent, GaussianModel* model) {
  for (ParamGroup group : kAllGroups) {
    std::vector<float>& v = GroupParams(*model, group);
    const size_t stride = GroupStride(*model, group);
    std::vector<float> out(parent.size() * stride);
    // SH degree 0 has no f_rest: indexing its empty vector would be UB.
    if (stride == 0) continue;
    for (size_t i = 0; i < parent.size(); ++i) {
      std::memcpy(out.data() + i * stride, v.data() + parent[i] * stride,
                  stride * sizeof(float));
    }
    v.swap(out);
  }
}

template <typename T>
void WriteVector(std::ostream& out, const std::vector<T>& v) {
  const uint64_t n = v.size();
  out.write(reinterpret_cast<const char*>(&n), sizeof(n));
  out.write(reinterpret_cast<const char*>(v.data()), n * sizeof(T));
}

template <typename T>
void ReadVector(std::istream& in, std::vector<T>* v) {
  uint64_t n = 0;
  in.read(reinterpret_cast<char*>(&n), sizeof(n));
  // Checked against the bytes left before allocating: a corrupt count must
  // not reserve gigabytes.
  const std::streampos here = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff left = in.tellg() - here;
  in.seekg(here);
  if (!in || n > uint64_t(left) / sizeof(T)) {
    Fail("density state: corrupt size");
  }
  v->resize(n);
  in.read(reinterpret_cast<char*>(v->data()), n * sizeof(T));
  if (!in) Fail("density state: truncated");
}

}  // namespace

InriaDensitySchedule::InriaDensitySchedule(const DensityOptions& o,
                                           int64_t iteration) {
  accumulates = iteration < o.densify_until_iter;
  if (!accumulates) return;
  densifies = iteration > o.densify_from_iter && o.densification_interval > 0 &&
              iteration % o.densification_interval == 0;
  size_limits = iteration > o.opacity_reset_interval;
  resets_opacity = (o.opacity_reset_interval > 0 &&
                    iteration % o.opacity_reset_interval == 0) ||
                   (o.white_background && iteration == o.densify_from_iter);
  wants_radii = o.max_screen_size > 0 && size_limits;
}

namespace {

class InriaDensityStrategy : public DensityStrategy {
 public:
  InriaDensityStrategy(const DensityOptions& options, double scene_extent)
      : options_(options), extent_(scene_extent), rng_(options.seed) {}

  void Init(const GaussianModel& model) override { ResetStats(model.size()); }

  bool WantsRadii(int64_t iteration) const override {
    return InriaDensitySchedule(options_, iteration).wants_radii;
  }

  bool ReadsGradients(int64_t iteration) const override {
    return InriaDensitySchedule(options_, iteration).accumulates;
  }

  // Exactly the iterations where PostBackward densifies or resets.
  bool MayChangeModel(int64_t iteration) const override {
    return InriaDensitySchedule(options_, iteration).MayChangeModel();
  }

  DensityEvent PostBackward(int64_t iteration, const GaussianGradients& grads,
                            const std::vector<float>* radii,
                            GaussianModel* model, Adam* adam) override {
    DensityEvent event;
    const InriaDensitySchedule schedule(options_, iteration);
    if (!schedule.accumulates) return event;
    if (grad_accum_.size() != model->size()) ResetStats(model->size());
    Accumulate(grads, radii);
    if (schedule.densifies) {
      DensifyAndPrune(schedule.size_limits, model, adam, &event);
    }
    if (schedule.resets_opacity) {
      ResetOpacity(model, adam);
      event.opacity_reset = true;
    }
    return event;
  }

  std::string SaveState() const override {
    return EncodeInriaDensityState(grad_accum_, denom_, max_radii_, rng_);
  }

  void LoadState(const std::string& bytes) override {
    DecodeInriaDensityState(bytes, &grad_accum_, &denom_, &max_radii_, &rng_);
  }

  size_t BytesPerGaussian() const override {
    return sizeof(float) + sizeof(uint16_t) + sizeof(float);
  }

 private:
  void ResetStats(size_t n) {
    grad_accum_.assign(n, 0.f);
    denom_.assign(n, 0);
    max_radii_.assign(n, 0.f);
  }

  // Inria's add_densification_stats and max_radii2D update.
  void Accumulate(const GaussianGradients& grads,
                  const std::vector<float>* radii) {
    const size_t n = grad_accum_.size();
    if (grads.visible.size() != n || grads.mean2d_grad_norm_ndc.size() != n) {
      Fail("density control: gradients for " +
           std::to_string(grads.visible.size()) + " Gaussians, model has " +
           std::to_string(n));
    }
    for (size_t i = 0; i < n; ++i) {
      if (!grads.visible[i]) continue;
      const float g = grads.mean2d_grad_norm_ndc[i];
      if (std::isfinite(g)) grad_accum_[i] += g;
      if (denom_[i] < std::numeric_limits<uint16_t>::max()) ++denom_[i];
      if (radii) max_radii_[i] = std::max(max_radii_[i], (*radii)[i]);
    }
  }

  void DensifyAndPrune(bool size_limits, GaussianModel* model, Adam* adam,
                       DensityEvent* event) {
    const size_t n = model->size();
    const float threshold = static_cast<float>(options_.grad_threshold);
    const float dense_scale =
        static_cast<float>(options_.percent_dense * extent_);
    // Order after densification, as Inria builds it: kept originals, clones,
    // then split samples (sample k of every split Gaussian, k = 0, 1, ...).
    std::vector<int64_t> parent;
    std::vector<int64_t> clones, splits;
    for (size_t i = 0; i < n; ++i) {
      const float avg = denom_[i] > 0 ? grad_accum_[i] / denom_[i] : 0.f;
      if (!(avg >= threshold)) {
        parent.push_back(static_cast<int64_t>(i));
        continue;
      }
      if (MaxScale(*model, i) <= dense_scale) {
        clones.push_back(static_cast<int64_t>(i));
        parent.push_back(static_cast<int64_t>(i));
      } else {
        splits.push_back(static_cast<int64_t>(i));
      }
    }
    const size_t kept = parent.size();
    parent.insert(parent.end(), clones.begin(), clones.end());
    for (int k = 0; k < options_.split_samples; ++k) {
      parent.insert(parent.end(), splits.begin(), splits.end());
    }
    std::vector<float> radii(parent.size(), 0.f);
    for (size_t j = 0; j < kept; ++j) radii[j] = max_radii_[parent[j]];

    GatherModel(parent, model);
    SampleSplits(kept + clones.size(), model);
    std::vector<bool> keep_in_adam(n, false);
    for (size_t j = 0; j < kept; ++j) keep_in_adam[parent[j]] = true;
    adam->Filter(keep_in_adam);
    adam->Append(parent.size() - kept);

    // Prune the densified set.
    const size_t m = model->size();
    std::vector<bool> keep(m, true);
    size_t pruned = 0;
    for (size_t j = 0; j < m; ++j) {
      bool prune = Sigmoid(model->opacity_logits[j]) <
                   static_cast<float>(options_.min_opacity);
      if (size_limits) {
        if (options_.max_screen_size > 0 &&
            radii[j] > options_.max_screen_size) {
          prune = true;
        }
        if (MaxScale(*model, j) > options_.max_world_size * extent_) {
          prune = true;
        }
      }
      keep[j] = !prune;
      pruned += prune;
    }
    if (pruned > 0) {
      model->Filter(keep);
      adam->Filter(keep);
      size_t out = 0;
      for (size_t j = 0; j < m; ++j) {
        if (keep[j]) parent[out++] = parent[j];
      }
      parent.resize(out);
    }
    event->densified = true;
    event->cloned = clones.size();
    event->split = splits.size();
    event->pruned = pruned;
    event->parent = std::move(parent);
    ResetStats(model->size());
  }

  // Split samples from index `first` on: position drawn from the parent's
  // Gaussian, scale divided by 0.8 * split_samples.
  void SampleSplits(size_t first, GaussianModel* model) {
    const float log_shrink =
        std::log(0.8f * static_cast<float>(options_.split_samples));
    std::normal_distribution<double> normal(0.0, 1.0);
    for (size_t j = first; j < model->size(); ++j) {
      float* mean = &model->means[3 * j];
      float* log_scale = &model->log_scales[3 * j];
      double R[9];
      Rotation(&model->quats[4 * j], R);
      double local[3];
      for (int a = 0; a < 3; ++a) {
        local[a] = normal(rng_) * std::exp(double(log_scale[a]));
      }
      for (int r = 0; r < 3; ++r) {
        mean[r] +=
            static_cast<float>(R[3 * r] * local[0] + R[3 * r + 1] * local[1] +
                               R[3 * r + 2] * local[2]);
      }
      for (int a = 0; a < 3; ++a) log_scale[a] -= log_shrink;
    }
  }

  void ResetOpacity(GaussianModel* model, Adam* adam) {
    for (float& logit : model->opacity_logits) {
      logit = ResetOpacityLogit(logit, options_.reset_opacity);
    }
    adam->ResetMoments(ParamGroup::kOpacity);
  }

  DensityOptions options_;
  double extent_;
  std::mt19937_64 rng_;
  // Per Gaussian: sum of view-space gradient norms, number of views it was
  // visible in, and its largest screen radius since the last densification.
  std::vector<float> grad_accum_;
  std::vector<uint16_t> denom_;
  std::vector<float> max_radii_;
};

class FixedDensityStrategy : public DensityStrategy {
 public:
  void Init(const GaussianModel&) override {}
  bool WantsRadii(int64_t) const override { return false; }
  bool ReadsGradients(int64_t) const override { return false; }
  bool MayChangeModel(int64_t) const override { return false; }
  DensityEvent PostBackward(int64_t, const GaussianGradients&,
                            const std::vector<float>*, GaussianModel*,
                            Adam*) override {
    return {};
  }
  std::string SaveState() const override { return {}; }
  void LoadState(const std::string&) override {}
  size_t BytesPerGaussian() const override { return 0; }
};

}  // namespace

float ResetOpacityLogit(float logit, double max_opacity) {
  // Below the cap the logit is kept as is (Inria's round trip through the
  // sigmoid would turn very negative logits into -inf).
  if (!(Sigmoid(logit) > max_opacity)) return logit;
  return static_cast<float>(std::log(max_opacity / (1.0 - max_opacity)));
}

std::unique_ptr<DensityStrategy> MakeInriaDensityStrategy(
    const DensityOptions& options, double scene_extent) {
  return std::make_unique<InriaDensityStrategy>(options, scene_extent);
}

std::unique_ptr<DensityStrategy> MakeFixedDensityStrategy() {
  return std::make_unique<FixedDensityStrategy>();
}

std::string EncodeInriaDensityState(const std::vector<float>& grad_accum,
                                    const std::vector<uint16_t>& denom,
                                    const std::vector<float>& max_radii,
                                    const std::mt19937_64& rng) {
  std::ostringstream out;
  WriteVector(out, grad_accum);
  WriteVector(out, denom);
  WriteVector(out, max_radii);
  out << rng;
  return out.str();
}

void DecodeInriaDensityState(const std::string& bytes,
                             std::vector<float>* grad_accum,
                             std::vector<uint16_t>* denom,
                             std::vector<float>* max_radii,
                             std::mt19937_64* rng) {
  std::istringstream in(bytes);
  ReadVector(in, grad_accum);
  ReadVector(in, denom);
  ReadVector(in, max_radii);
  in >> *rng;
  if (!in || denom->size() != grad_accum->size() ||
      max_radii->size() != grad_accum->size()) {
    Fail("density state: inconsistent statistics");
  }
}

}  // namespace watergs
