// Adam for GaussianModel parameter groups (see adam.h).
#include "gaussian/adam.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "gaussian/sh.h"
#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr ParamGroup kGroups[kNumParamGroups] = {
    ParamGroup::kXyz,     ParamGroup::kFDc,     ParamGroup::kFRest,
    ParamGroup::kOpacity, ParamGroup::kScaling, ParamGroup::kRotation};

// Gradients beyond this are clamped so that g * g stays finite in float.
constexpr float kMaxGradMagnitude = 1e18f;
constexpr float kFloatMax = std::numeric_limits<float>::max();

// Gaussians per block of an Adam step.
constexpr int64_t kBlockGaussians = 256;

bool IsShGroup(ParamGroup group) {
  return group == ParamGroup::kFDc || group == ParamGroup::kFRest;
}

// Values [begin, end) of one group; branch-free so that it vectorises.
// Returns the number of rejected values (non-finite gradient or result).
template <typename Constants>
size_t AdamUpdate(const Constants& k, const float* gr, float* m, float* v,
                  float* p, size_t begin, size_t end) {
  const float step_size = k.step_size, bias2_sqrt = k.bias2_sqrt, w1 = k.w1,
              beta2 = k.beta2, w2 = k.w2, eps = k.eps;
  size_t bad = 0;
#pragma omp simd reduction(+ : bad)
  for (size_t j = begin; j < end; ++j) {
    const float raw = gr[j];
    const bool finite_grad = std::fabs(raw) <= kFloatMax;  // NaN: false
    const float g = finite_grad ? std::min(std::max(raw, -kMaxGradMagnitude),
                                           kMaxGradMagnitude)
                                : 0.f;
    const float new_m = m[j] + w1 * (g - m[j]);
    const float new_v = v[j] * beta2 + w2 * g * g;
    const float denom = std::sqrt(new_v) / bias2_sqrt + eps;
    const float new_p = p[j] - step_size * (new_m / denom);
    const bool ok = std::fabs(new_p) <= kFloatMax && new_v <= kFloatMax;
    bad += (finite_grad ? 0 : 1) + (ok ? 0 : 1);
    m[j] = ok ? new_m : m[j];
    v[j] = ok ? new_v : v[j];
    p[j] = ok ? new_p : p[j];
  }
  return bad;
}

// Gradients of Gaussians [i0, i1) of f_dc or f_rest from the factored
// (compact_sh) form, into `out`; returns out->data().
const float* ExpandShGradients(const GaussianGradients& grads, ParamGroup group,
                               int64_t i0, int64_t i1, int stride,
                               std::vector<float>* out) {
  const int rest_stride = group == ParamGroup::kFRest ? stride : 45;
  out->resize(static_cast<size_t>(i1 - i0) * stride);
  float dc[3], rest[45];
  for (int64_t i = i0; i < i1; ++i) {
    ShCoefficientGradients(grads.sh_active_degree, &grads.sh_view_dir[3 * i],
                           &grads.sh_color_grad[3 * i], rest_stride, dc, rest);
    float* dst = out->data() + static_cast<size_t>(i - i0) * stride;
    std::copy_n(group == ParamGroup::kFDc ? dc : rest, stride, dst);
  }
  return out->data();
}

// bfloat16 storage of moments: the top 16 bits of a float.
float* DecodeBf16(const uint16_t* in, size_t count, std::vector<float>* out) {
  out->resize(count);
  for (size_t j = 0; j < count; ++j) {
    const uint32_t bits = static_cast<uint32_t>(in[j]) << 16;
    std::memcpy(&(*out)[j], &bits, sizeof(float));
  }
  return out->data();
}

// A non-zero xorshift32 state from a step-and-group seed and a block index.
uint32_t RoundingState(uint64_t seed, uint64_t block) {
  uint64_t z = seed * 0x9e3779b97f4a7c15ull + block + 0x632be59bd9b4e019ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  const uint32_t state = static_cast<uint32_t>(z ^ (z >> 31));
  return state == 0 ? 1u : state;
}

// Float -> bfloat16 with stochastic rounding of the magnitude: the expected
// stored value is the float, so Adam's small per-step EMA increments (0.1%
// of v, under bfloat16's 0.4% spacing) accumulate instead of rounding away.
void EncodeBf16Stochastic(const float* in, size_t count, uint32_t* state,
                          uint16_t* out) {
  uint32_t x = *state;
  for (size_t j = 0; j < count; ++j) {
    x ^= x << 13, x ^= x >> 17, x ^= x << 5;
    uint32_t bits;
    std::memcpy(&bits, &in[j], sizeof(float));
    // Moments are finite and at most ~1e36, so the carry never reaches Inf.
    out[j] = static_cast<uint16_t>((bits + (x & 0xffffu)) >> 16);
  }
  *state = x;
}

template <typename V>
void FilterRows(V& v, const std::vector<bool>& keep, size_t stride) {
  if (v.empty()) return;  // the storage the other moment layout uses
  size_t out = 0;
  for (size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    if (out != i) {
      std::copy_n(v.begin() + i * stride, stride, v.begin() + out * stride);
    }
    ++out;
  }
  v.resize(out * stride);
}

// Decoded values of every 8-bit moment code.
struct MomentCodeTable {
  float value[256];
  MomentCodeTable() {
    for (int c = 0; c < 256; ++c) {
      const int magnitude = c & 127;
      const int exponent = (magnitude >> 3) - 8;
      const float mantissa = 1.f + (magnitude & 7) / 8.f;
      const float v = magnitude == 0 ? 0.f : std::ldexp(mantissa, exponent);
      value[c] = (c & 128) ? -v : v;
    }
  }
};

const MomentCodeTable& CodeTable() {
  static const MomentCodeTable table;
  return table;
}

}  // namespace

uint8_t EncodeMomentCode(float x) {
  if (!std::isfinite(x)) return 0;
  const uint8_t sign = x < 0 ? 128 : 0;
  uint32_t bits;
  const float a = std::fabs(x);
  std::memcpy(&bits, &a, sizeof(bits));
  bits += 1u << 19;  // round the 20 dropped mantissa bits to nearest
  const int exponent = static_cast<int>(bits >> 23) - 127;
  if (exponent < -8) return 0;
  if (exponent > 7) return sign | 127;
  const int magnitude = ((exponent + 8) << 3) | ((bits >> 20) & 7);
  return magnitude == 0 ? 0 : static_cast<uint8_t>(sign | magnitude);
}

float DecodeMomentCode(uint8_t code) { return CodeTable().value[code]; }

double ExponentialLr(int64_t step, double lr_init, double lr_final,
                     int64_t delay_steps, double delay_mult,
                     int64_t max_steps) {
  if (step < 0 || (lr_init == 0.0 && lr_final == 0.0)) return 0.0;
  double delay_rate = 1.0;
  if (delay_steps > 0) {
    const double s = std::clamp(double(step) / double(delay_steps), 0.0, 1.0);
    delay_rate = delay_mult + (1 - delay_mult) * std::sin(0.5 * M_PI * s);
  }
  const double t = max_steps > 0
                       ? std::clamp(double(step) / double(max_steps), 0.0, 1.0)
                       : 1.0;
  const double log_lerp =
      std::exp(std::log(lr_init) * (1 - t) + std::log(lr_final) * t);
  return delay_rate * log_lerp;
}

std::vector<float>& GroupParams(GaussianModel& model, ParamGroup group) {
  switch (group) {
    case ParamGroup::kXyz:
      return model.means;
    case ParamGroup::kFDc:
      return model.sh_dc;
    case ParamGroup::kFRest:
      return model.sh_rest;
    case ParamGroup::kOpacity:
      return model.opacity_logits;
    case ParamGroup::kScaling:
      return model.log_scales;
    case ParamGroup::kRotation:
      return model.quats;
  }
  return model.means;
}

const std::vector<float>& GroupParams(const GaussianModel& model,
                                      ParamGroup group) {
  return GroupParams(const_cast<GaussianModel&>(model), group);
}

const std::vector<float>& GroupGrads(const GaussianGradients& grads,
                                     ParamGroup group) {
  switch (group) {
    case ParamGroup::kXyz:
      return grads.means;
    case ParamGroup::kFDc:
      return grads.sh_dc;
    case ParamGroup::kFRest:
      return grads.sh_rest;
    case ParamGroup::kOpacity:
      return grads.opacity_logits;
    case ParamGroup::kScaling:
      return grads.log_scales;
    case ParamGroup::kRotation:
      return grads.quats;
  }
  return grads.means;
}

int GroupStride(const GaussianModel& model, ParamGroup group) {
  switch (group) {
    case ParamGroup::kXyz:
    case ParamGroup::kFDc:
    case ParamGroup::kScaling:
      return 3;
    case ParamGroup::kFRest:
      return model.sh_rest_stride();
    case ParamGroup::kOpacity:
      return 1;
    case ParamGroup::kRotation:
      return 4;
  }
  return 0;
}

const char* GroupName(ParamGroup group) {
  switch (group) {
    case ParamGroup::kXyz:
      return "xyz";
    case ParamGroup::kFDc:
      return "f_dc";
    case ParamGroup::kFRest:
      return "f_rest";
    case ParamGroup::kOpacity:
      return "opacity";
    case ParamGroup::kScaling:
      return "scaling";
    case ParamGroup::kRotation:
      return "rotation";
  }
  return "?";
}

Adam::Adam(const AdamOptions& options, double scene_extent)
    : options_(options), scene_extent_(scene_extent) {
  enabled_.fill(true);
  SetIteration(0);
}

void Adam::Init(const GaussianModel& model) {
  num_gaussians_ = model.size();
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    strides_[g] = GroupStride(model, group);
    const size_t n = num_gaussians_ * strides_[g];
    AdamGroupState& s = groups_[g];
    s = AdamGroupState{};
    if (options_.compact_moments) {
      s.exp_avg_q.assign(n, 0);
      s.exp_avg_sq_shared.assign(num_gaussians_, 0.f);
    } else if (UsesHalfMoments(group)) {
      s.exp_avg_h.assign(n, 0);
      s.exp_avg_sq_h.assign(n, 0);
    } else {
      s.exp_avg.assign(n, 0.f);
      s.exp_avg_sq.assign(n, 0.f);
    }
    masks_[g].clear();
  }
  rejected_total_ = 0;
}

std::array<double, kNumParamGroups> GroupLearningRates(const AdamOptions& o,
                                                       double scene_extent,
                                                       int64_t iteration) {
  std::array<double, kNumParamGroups> lr{};
  lr[static_cast<int>(ParamGroup::kXyz)] = ExponentialLr(
      iteration, o.position_lr_init * scene_extent,
      o.position_lr_final * scene_extent, o.position_lr_delay_steps,
      o.position_lr_delay_mult, o.position_lr_max_steps);
  lr[static_cast<int>(ParamGroup::kFDc)] = o.feature_lr;
  lr[static_cast<int>(ParamGroup::kFRest)] = o.feature_rest_lr;
  lr[static_cast<int>(ParamGroup::kOpacity)] = o.opacity_lr;
  lr[static_cast<int>(ParamGroup::kScaling)] = o.scaling_lr;
  lr[static_cast<int>(ParamGroup::kRotation)] = o.rotation_lr;
  return lr;
}

void Adam::SetIteration(int64_t iteration) {
  lr_ = GroupLearningRates(options_, scene_extent_, iteration);
}

bool Adam::UsesHalfMoments(ParamGroup group) const {
  return options_.half_moments && !options_.compact_moments &&
         group != ParamGroup::kXyz;
}

double Adam::LearningRate(ParamGroup group) const { return lr_[Index(group)]; }

void Adam::SetLearningRate(ParamGroup group, double lr) {
  lr_[Index(group)] = lr;
}

void Adam::SetGroupEnabled(ParamGroup group, bool enabled) {
  enabled_[Index(group)] = enabled;
}

bool Adam::GroupEnabled(ParamGroup group) const {
  return enabled_[Index(group)];
}

void Adam::SetGaussianMask(ParamGroup group, std::vector<uint8_t> mask) {
  if (!mask.empty() && mask.size() != num_gaussians_) {
    Fail("Adam: mask for " + std::string(GroupName(group)) + " has " +
         std::to_string(mask.size()) + " entries, model has " +
         std::to_string(num_gaussians_));
  }
  masks_[Index(group)] = std::move(mask);
}

size_t Adam::Step(const GaussianGradients& grads, GaussianModel* model) {
  if (model->size() != num_gaussians_) {
    Fail("Adam: model has " + std::to_string(model->size()) +
         " Gaussians, optimiser state " + std::to_string(num_gaussians_));
  }
  size_t rejected = 0;
  for (ParamGroup group : kGroups) {
    const int g = Index(group);
    if (!enabled_[g]) continue;
    std::vector<float>& params = GroupParams(*model, group);
    const bool factored = IsShGroup(group) && grads.compact_sh;
    const std::vector<float>& grad =
        factored ? grads.sh_color_grad : GroupGrads(grads, group);
    const size_t expected = factored ? 3 * num_gaussians_ : params.size();
    if (grad.size() != expected ||
        (factored && grads.sh_view_dir.size() != expected) ||
        params.size() != num_gaussians_ * strides_[g]) {
      Fail(std::string("Adam: gradient of ") + GroupName(group) + " has " +
           std::to_string(grad.size()) + " values, expected " +
           std::to_string(expected));
    }
    if (factored && options_.compact_moments) {
      Fail("Adam: compact moments need dense SH gradients (compact_sh off)");
    }
    rejected += options_.compact_moments
                    ? StepGroupCompact(group, grad, strides_[g], &params)
                    : StepGroup(group, grads, strides_[g], &params);
  }
  rejected_total_ += static_cast<int64_t>(rejected);
  return rejected;
}

Adam::StepConstants Adam::NextStepConstants(ParamGroup group,
                                            AdamGroupState* state) const {
  ++state->step;
  const double bias1 = 1.0 - std::pow(options_.beta1, double(state->step));
  const double bias2 = 1.0 - std::pow(options_.beta2, double(state->step));
  return {static_cast<float>(lr_[Index(group)] / bias1),
          static_cast<float>(std::sqrt(bias2)),
          static_cast<float>(1.0 - options_.beta1),
          static_cast<float>(options_.beta2),
          static_cast<float>(1.0 - options_.beta2),
          static_cast<float>(options_.eps)};
}

size_t Adam::StepGroup(ParamGroup group, const GaussianGradients& grads,
                       int stride, std::vector<float>* params) {
  AdamGroupState& s = groups_[Index(group)];
  // torch.optim.Adam (single-tensor path), in float like torch.
  const StepConstants k = NextStepConstants(group, &s);
  const std::vector<uint8_t>& mask = masks_[Index(group)];
  const bool use_mask = !mask.empty();
  const bool half = UsesHalfMoments(group);
  const bool expand_sh = IsShGroup(group) && grads.compact_sh;
  const float* dense = expand_sh ? nullptr : GroupGrads(grads, group).data();
  const uint64_t rounding_seed = (static_cast<uint64_t>(s.step) << 8) ^
                                 static_cast<uint64_t>(Index(group));
  const int64_t n = static_cast<int64_t>(num_gaussians_);
  const int64_t blocks = (n + kBlockGaussians - 1) / kBlockGaussians;
  size_t rejected = 0;
  // Fixed blocks (not per-thread ranges) so that stochastic rounding, seeded
  // per block, gives the same result for any thread count.
#pragma omp parallel for schedule(static) reduction(+ : rejected) \
    if (n * stride > 32768)
  for (int64_t b = 0; b < blocks; ++b) {
    thread_local std::vector<float> g_buf, m_buf, v_buf;
    const int64_t i0 = b * kBlockGaussians;
    const int64_t i1 = std::min(n, i0 + kBlockGaussians);
    const size_t v0 = static_cast<size_t>(i0) * stride;
    const size_t count = static_cast<size_t>(i1 - i0) * stride;
    const float* g =
        expand_sh ? ExpandShGradients(grads, group, i0, i1, stride, &g_buf)
                  : dense + v0;
    // (The unused layout's vectors are empty: no offsets into them.)
    float* m = half ? DecodeBf16(s.exp_avg_h.data() + v0, count, &m_buf)
                    : s.exp_avg.data() + v0;
    float* v = half ? DecodeBf16(s.exp_avg_sq_h.data() + v0, count, &v_buf)
                    : s.exp_avg_sq.data() + v0;
    float* p = params->data() + v0;
    if (use_mask) {
      for (int64_t i = i0; i < i1; ++i) {
        const size_t at = static_cast<size_t>(i - i0) * stride;
        if (mask[i]) rejected += AdamUpdate(k, g, m, v, p, at, at + stride);
      }
    } else {
      rejected += AdamUpdate(k, g, m, v, p, 0, count);
    }
    if (half) {
      uint32_t state = RoundingState(rounding_seed, static_cast<uint64_t>(b));
      EncodeBf16Stochastic(m, count, &state, s.exp_avg_h.data() + v0);
      EncodeBf16Stochastic(v, count, &state, s.exp_avg_sq_h.data() + v0);
    }
  }
  return rejected;
}

size_t Adam::StepGroupCompact(ParamGroup group, const std::vector<float>& grad,
                              int stride, std::vector<float>* params) {
  AdamGroupState& s = groups_[Index(group)];
  // torch.optim.Adam (single-tensor path), in float like torch.
  // Plain copies, not a structured binding, since the lambda below captures
  // them (clang before 16 cannot capture structured bindings).
  const StepConstants k = NextStepConstants(group, &s);
  const float step_size = k.step_size, bias2_sqrt = k.bias2_sqrt, w1 = k.w1,
              beta2 = k.beta2, w2 = k.w2, eps = k.eps;
  const std::vector<uint8_t>& mask = masks_[Index(group)];
  const bool use_mask = !mask.empty();
  float* p = params->data();
  uint8_t* q = s.exp_avg_q.data();
  float* v = s.exp_avg_sq_shared.data();
  const float* gr = grad.data();
  const float* table = CodeTable().value;
  const int64_t n = static_cast<int64_t>(num_gaussians_);
  size_t rejected = 0;
#pragma omp parallel for schedule(static) reduction(+ : rejected) \
    if (n * stride > 32768)
  for (int64_t i = 0; i < n; ++i) {
    if (use_mask && !mask[i]) continue;
    float g[64], m[64];
    const size_t base = static_cast<size_t>(i) * stride;
    float mean_sq = 0.f;
    size_t bad = 0;
    for (int k = 0; k < stride; ++k) {
      float x = gr[base + k];
      if (!std::isfinite(x)) {
        x = 0.f;
        ++bad;
      }
      g[k] = std::clamp(x, -kMaxGradMagnitude, kMaxGradMagnitude);
      mean_sq += g[k] * g[k] / static_cast<float>(stride);
    }
    const float old_rms = std::sqrt(v[i]);
    const float new_v = v[i] * beta2 + w2 * mean_sq;
    const float new_rms = std::sqrt(new_v);
    const float denom = new_rms / bias2_sqrt + eps;
    bool finite = std::isfinite(new_v);
    for (int k = 0; k < stride; ++k) {
      const float old_m = table[q[base + k]] * old_rms;
      m[k] = old_m + w1 * (g[k] - old_m);
      finite = finite && std::isfinite(p[base + k] - step_size * m[k] / denom);
    }
    rejected += bad;
    if (!finite) {
      ++rejected;
      continue;
    }
    const float inv_rms = new_rms > 0 ? 1.f / new_rms : 0.f;
    for (int k = 0; k < stride; ++k) {
      p[base + k] -= step_size * (m[k] / denom);
      q[base + k] = EncodeMomentCode(m[k] * inv_rms);
    }
    v[i] = new_v;
  }
  return rejected;
}

void Adam::Filter(const std::vector<bool>& keep) {
  if (keep.size() != num_gaussians_) {
    Fail("Adam::Filter: keep has " + std::to_string(keep.size()) +
         " entries, optimiser state " + std::to_string(num_gaussians_));
  }
  for (int g = 0; g < kNumParamGroups; ++g) {
    FilterRows(groups_[g].exp_avg, keep, strides_[g]);
    FilterRows(groups_[g].exp_avg_sq, keep, strides_[g]);
    FilterRows(groups_[g].exp_avg_q, keep, strides_[g]);
    FilterRows(groups_[g].exp_avg_sq_shared, keep, 1);
    FilterRows(groups_[g].exp_avg_h, keep, strides_[g]);
    FilterRows(groups_[g].exp_avg_sq_h, keep, strides_[g]);
    if (!masks_[g].empty()) FilterRows(masks_[g], keep, 1);
  }
  num_gaussians_ =
      static_cast<size_t>(std::count(keep.begin(), keep.end(), true));
}

void Adam::Append(size_t count) {
  num_gaussians_ += count;
  for (int g = 0; g < kNumParamGroups; ++g) {
    AdamGroupState& s = groups_[g];
    if (options_.compact_moments) {
      s.exp_avg_q.resize(num_gaussians_ * strides_[g], 0);
      s.exp_avg_sq_shared.resize(num_gaussians_, 0.f);
    } else if (UsesHalfMoments(static_cast<ParamGroup>(g))) {
      s.exp_avg_h.resize(num_gaussians_ * strides_[g], 0);
      s.exp_avg_sq_h.resize(num_gaussians_ * strides_[g], 0);
    } else {
      s.exp_avg.resize(num_gaussians_ * strides_[g], 0.f);
      s.exp_avg_sq.resize(num_gaussians_ * strides_[g], 0.f);
    }
    if (!masks_[g].empty()) masks_[g].resize(num_gaussians_, 1);
  }
}

void Adam::ResetMoments(ParamGroup group) {
  AdamGroupState& s = groups_[Index(group)];
  std::fill(s.exp_avg.begin(), s.exp_avg.end(), 0.f);
  std::fill(s.exp_avg_sq.begin(), s.exp_avg_sq.end(), 0.f);
  std::fill(s.exp_avg_q.begin(), s.exp_avg_q.end(), 0);
  std::fill(s.exp_avg_sq_shared.begin(), s.exp_avg_sq_shared.end(), 0.f);
  std::fill(s.exp_avg_h.begin(), s.exp_avg_h.end(), 0);
  std::fill(s.exp_avg_sq_h.begin(), s.exp_avg_sq_h.end(), 0);
}

size_t Adam::BytesPerGaussian() const {
  size_t bytes = 0;
  for (int g = 0; g < kNumParamGroups; ++g) {
    const size_t moment_bytes = UsesHalfMoments(static_cast<ParamGroup>(g))
                                    ? sizeof(uint16_t)
                                    : sizeof(float);
    bytes += options_.compact_moments
                 ? strides_[g] * sizeof(uint8_t) + sizeof(float)
                 : 2 * moment_bytes * strides_[g];
    if (!masks_[g].empty()) bytes += 1;
  }
  return bytes;
}

void ScaleRates(double scale, AdamOptions* options) {
  for (double* rate :
       {&options->position_lr_init, &options->position_lr_final,
        &options->feature_lr, &options->feature_rest_lr, &options->opacity_lr,
        &options->scaling_lr, &options->rotation_lr}) {
    *rate *= scale;
  }
}

}  // namespace watergs
