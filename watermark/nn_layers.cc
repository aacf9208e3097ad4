// CPU implementations of the neural-network layers (see nn_layers.h).
#include "watermark/nn_layers.h"

#include <Eigen/Core>
#include <cmath>
#include <cstring>

namespace watergs {
namespace {

using RowMatrix =
    Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using MapMatrix = Eigen::Map<RowMatrix>;
using ConstMapMatrix = Eigen::Map<const RowMatrix>;

// Loops below this many values run on one thread: on a busy machine every
// fork/join waits for a time slice of each thread, which costs more than
// small loops save.
constexpr size_t kParallelMin = size_t(1) << 18;

// PyTorch's default initialisation: U(-1/sqrt(fan_in), 1/sqrt(fan_in)).
void UniformInit(Parameter* p, int fan_in, std::mt19937* rng) {
  const float bound = 1.f / std::sqrt(float(fan_in));
  std::uniform_real_distribution<float> dist(-bound, bound);
  for (float& x : p->value) x = dist(*rng);
}

// col [(ci*k + ky)*k + kx][y*W + x] = image[ci][y + ky - pad][x + kx - pad].
void Im2Col(const float* image, int channels, int height, int width, int k,
            float* col) {
  const int pad = k / 2;
  const size_t hw = size_t(height) * width;
#pragma omp parallel for schedule(static) if (hw * channels * k * k >= \
                                              kParallelMin)
  for (int ci = 0; ci < channels; ++ci) {
    for (int ky = 0; ky < k; ++ky) {
      for (int kx = 0; kx < k; ++kx) {
        float* row = col + (size_t(ci * k + ky) * k + kx) * hw;
        const float* plane = image + size_t(ci) * hw;
        for (int y = 0; y < height; ++y) {
          const int sy = y + ky - pad;
          float* out = row + size_t(y) * width;
          if (sy < 0 || sy >= height) {
            std::memset(out, 0, sizeof(float) * width);
            continue;
          }
          const float* in = plane + size_t(sy) * width;
          // Columns read from inside the image: [x0, x1), empty when the
          // padding is wider than the image.
          const int x0 = std::min(width, std::max(0, pad - kx));
          const int x1 = std::max(x0, std::min(width, width + pad - kx));
          for (int x = 0; x < x0; ++x) out[x] = 0.f;
          if (x1 > x0) {
            std::memcpy(out + x0, in + x0 + kx - pad,
                        sizeof(float) * (x1 - x0));
          }
          for (int x = x1; x < width; ++x) out[x] = 0.f;
        }
      }
    }
  }
}

}  // namespace

Parameter::Parameter(std::string name_, std::vector<int> shape_,
                     bool trainable_)
    : name(std::move(name_)), shape(std::move(shape_)), trainable(trainable_) {
  size_t n = 1;
  for (int d : shape) n *= size_t(d);
  value.assign(n, 0.f);
  grad.assign(trainable ? n : 0, 0.f);
}

Conv2d::Conv2d(const std::string& name, int in_channels, int out_channels,
               int kernel, std::mt19937* rng)
    : weight(name + ".weight", {out_channels, in_channels, kernel, kernel}),
      bias(name + ".bias", {out_channels}),
      in_(in_channels),
      out_(out_channels),
      kernel_(kernel) {
  UniformInit(&weight, in_channels * kernel * kernel, rng);
  UniformInit(&bias, in_channels * kernel * kernel, rng);
}

void Conv2d::Forward(const Tensor& x, Tensor* y) {
  y->Resize(x.n, out_, x.h, x.w);
  const int hw = x.h * x.w;
  const int k_rows = in_ * kernel_ * kernel_;
  ConstMapMatrix w(weight.value.data(), out_, k_rows);
  if (kernel_ > 1) col_.resize(size_t(k_rows) * hw);
  for (int b = 0; b < x.n; ++b) {
    const float* col = x.Plane(b, 0);
    if (kernel_ > 1) {
      Im2Col(x.Plane(b, 0), in_, x.h, x.w, kernel_, col_.data());
      col = col_.data();
    }
    MapMatrix out(y->Plane(b, 0), out_, hw);
    out.noalias() = w * ConstMapMatrix(col, k_rows, hw);
    out.colwise() += Eigen::Map<const Eigen::VectorXf>(bias.value.data(), out_);
  }
}

void Conv2d::Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                      bool weight_grads) {
  const int hw = x.h * x.w;
  const int k_rows = in_ * kernel_ * kernel_;
  ConstMapMatrix w(weight.value.data(), out_, k_rows);
  if (dx) dx->ResizeLike(x);
  if (kernel_ > 1) col_.resize(size_t(k_rows) * hw);
  if (dx && kernel_ > 1) {
    // flipped[ci][(co*k + ky)*k + kx] = weight[co][ci][k-1-ky][k-1-kx].
    const int kk = kernel_ * kernel_;
    flipped_.resize(size_t(in_) * out_ * kk);
    dy_col_.resize(size_t(out_) * kk * hw);
    for (int co = 0; co < out_; ++co)
      for (int ci = 0; ci < in_; ++ci)
        for (int t = 0; t < kk; ++t)
          flipped_[(size_t(ci) * out_ + co) * kk + t] =
              weight.value[(size_t(co) * in_ + ci) * kk + (kk - 1 - t)];
  }
  for (int b = 0; b < x.n; ++b) {
    ConstMapMatrix grad_out(dy.Plane(b, 0), out_, hw);
    if (weight_grads) {
      const float* col = x.Plane(b, 0);
      if (kernel_ > 1) {
        Im2Col(x.Plane(b, 0), in_, x.h, x.w, kernel_, col_.data());
        col = col_.data();
      }
      MapMatrix(weight.grad.data(), out_, k_rows).noalias() +=
          grad_out * ConstMapMatrix(col, k_rows, hw).transpose();
      AddRowSums(dy.Plane(b, 0), out_, hw, bias.grad.data());
    }
    if (!dx) continue;
    if (kernel_ == 1) {
      MapMatrix(dx->Plane(b, 0), in_, hw).noalias() = w.transpose() * grad_out;
    } else {
      // Backward-data of a stride-1 'same' convolution is a forward
      // convolution of dy with the flipped, transposed kernel: one im2col of
      // dy and one GEMM, as fast as Forward (no col2im scatter).
      Im2Col(dy.Plane(b, 0), out_, x.h, x.w, kernel_, dy_col_.data());
      MapMatrix(dx->Plane(b, 0), in_, hw).noalias() =
          ConstMapMatrix(flipped_.data(), in_, out_ * kernel_ * kernel_) *
          ConstMapMatrix(dy_col_.data(), out_ * kernel_ * kernel_, hw);
    }
  }
}

BatchNorm2d::BatchNorm2d(const std::string& name, int channels)
    : gamma(name + ".weight", {channels}),
      beta(name + ".bias", {channels}),
      running_mean(name + ".running_mean", {channels}, false),
      running_var(name + ".running_var", {channels}, false),
      mean_(channels),
      invstd_(channels) {
  std::fill(gamma.value.begin(), gamma.value.end(), 1.f);
  std::fill(running_var.value.begin(), running_var.value.end(), 1.f);
}

void BatchNorm2d::Forward(const Tensor& x, Tensor* y, bool training) {
  y->ResizeLike(x);
  const size_t hw = x.PlaneSize();
  const double count = double(x.n) * hw;
#pragma omp parallel for schedule(static) if (x.size() >= kParallelMin)
  for (int c = 0; c < x.c; ++c) {
    double mean, var;
    if (training) {
      // Two passes in double: exact enough for 1e6-pixel batches.
      double sum = 0.0;
      for (int b = 0; b < x.n; ++b) {
        const float* p = x.Plane(b, c);
        for (size_t i = 0; i < hw; ++i) sum += p[i];
      }
      mean = sum / count;
      double sq = 0.0;
      for (int b = 0; b < x.n; ++b) {
        const float* p = x.Plane(b, c);
        for (size_t i = 0; i < hw; ++i) sq += (p[i] - mean) * (p[i] - mean);
      }
      var = sq / count;
      const double unbiased = count > 1 ? sq / (count - 1) : var;
      running_mean.value[c] =
          float((1 - momentum) * running_mean.value[c] + momentum * mean);
      running_var.value[c] =
          float((1 - momentum) * running_var.value[c] + momentum * unbiased);
    } else {
      mean = running_mean.value[c];
      var = running_var.value[c];
    }
    mean_[c] = mean;
    invstd_[c] = 1.0 / std::sqrt(var + eps);
    const float scale = float(gamma.value[c] * invstd_[c]);
    const float shift =
        float(beta.value[c] - mean * gamma.value[c] * invstd_[c]);
    for (int b = 0; b < x.n; ++b) {
      const float* p = x.Plane(b, c);
      float* q = y->Plane(b, c);
      for (size_t i = 0; i < hw; ++i) q[i] = p[i] * scale + shift;
    }
  }
}

void BatchNorm2d::Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                           bool weight_grads, bool training) {
  if (dx) dx->ResizeLike(x);
  const size_t hw = x.PlaneSize();
  const double count = double(x.n) * hw;
#pragma omp parallel for schedule(static) if (x.size() >= kParallelMin)
  for (int c = 0; c < x.c; ++c) {
    const double mean = mean_[c], invstd = invstd_[c];
    double sum_dy = 0.0, sum_dy_xhat = 0.0;
    if (training || weight_grads) {
      for (int b = 0; b < x.n; ++b) {
        const float* p = x.Plane(b, c);
        const float* g = dy.Plane(b, c);
        for (size_t i = 0; i < hw; ++i) {
          sum_dy += g[i];
          sum_dy_xhat += g[i] * (p[i] - mean) * invstd;
        }
      }
    }
    if (weight_grads) {
      gamma.grad[c] += float(sum_dy_xhat);
      beta.grad[c] += float(sum_dy);
    }
    if (!dx) continue;
    const double scale = gamma.value[c] * invstd;
    // Training mode: the batch mean and variance depend on x too.
    const double mean_dy = training ? sum_dy / count : 0.0;
    const double mean_dy_xhat = training ? sum_dy_xhat / count : 0.0;
    for (int b = 0; b < x.n; ++b) {
      const float* p = x.Plane(b, c);
      const float* g = dy.Plane(b, c);
      float* q = dx->Plane(b, c);
      for (size_t i = 0; i < hw; ++i) {
        const double xhat = (p[i] - mean) * invstd;
        q[i] = float(scale * (g[i] - mean_dy - xhat * mean_dy_xhat));
      }
    }
  }
}

void ReluForward(Tensor* x) {
  float* p = x->data.data();
  const size_t n = x->size();
#pragma omp parallel for simd schedule(static) if (n >= kParallelMin)
  for (size_t i = 0; i < n; ++i) p[i] = p[i] > 0.f ? p[i] : 0.f;
}

void ReluBackward(const Tensor& y, Tensor* dy) {
  const float* p = y.data.data();
  float* g = dy->data.data();
  const size_t n = y.size();
#pragma omp parallel for simd schedule(static) if (n >= kParallelMin)
  for (size_t i = 0; i < n; ++i) g[i] = p[i] > 0.f ? g[i] : 0.f;
}

void GlobalAvgPoolForward(const Tensor& x, Tensor* y) {
  y->Resize(x.n, x.c, 1, 1);
  const size_t hw = x.PlaneSize();
  for (int b = 0; b < x.n; ++b) {
    for (int c = 0; c < x.c; ++c) {
      const float* p = x.Plane(b, c);
      double sum = 0.0;
      for (size_t i = 0; i < hw; ++i) sum += p[i];
      y->data[size_t(b) * x.c + c] = float(sum / double(hw));
    }
  }
}

void GlobalAvgPoolBackward(const Tensor& dy, const Tensor& like, Tensor* dx) {
  dx->ResizeLike(like);
  const size_t hw = like.PlaneSize();
  for (int b = 0; b < like.n; ++b) {
    for (int c = 0; c < like.c; ++c) {
      const float g = dy.data[size_t(b) * like.c + c] / float(hw);
      std::fill(dx->Plane(b, c), dx->Plane(b, c) + hw, g);
    }
  }
}

Linear::Linear(const std::string& name, int in_features, int out_features,
               std::mt19937* rng)
    : weight(name + ".weight", {out_features, in_features}),
      bias(name + ".bias", {out_features}),
      in_(in_features),
      out_(out_features) {
  UniformInit(&weight, in_features, rng);
  UniformInit(&bias, in_features, rng);
}

void Linear::Forward(const Tensor& x, Tensor* y) const {
  y->Resize(x.n, out_, 1, 1);
  for (int b = 0; b < x.n; ++b) {
    for (int o = 0; o < out_; ++o) {
      double sum = bias.value[o];
      const float* row = &weight.value[size_t(o) * in_];
      for (int i = 0; i < in_; ++i) sum += row[i] * x.data[size_t(b) * in_ + i];
      y->data[size_t(b) * out_ + o] = float(sum);
    }
  }
}

void Linear::Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                      bool weight_grads) {
  if (dx) {
    dx->ResizeLike(x);
    dx->Fill(0.f);
  }
  for (int b = 0; b < x.n; ++b) {
    for (int o = 0; o < out_; ++o) {
      const float g = dy.data[size_t(b) * out_ + o];
      const float* row = &weight.value[size_t(o) * in_];
      for (int i = 0; i < in_; ++i) {
        if (dx) dx->data[size_t(b) * in_ + i] += g * row[i];
        if (weight_grads)
          weight.grad[size_t(o) * in_ + i] += g * x.data[size_t(b) * in_ + i];
      }
      if (weight_grads) bias.grad[o] += g;
    }
  }
}

void AddRowSums(const float* rows, int num_rows, size_t row_length,
                float* sums) {
  for (int r = 0; r < num_rows; ++r) {
    const float* row = rows + size_t(r) * row_length;
    float sum = 0.f;
    for (size_t i = 0; i < row_length; ++i) sum += row[i];
    sums[r] += sum;
  }
}

double BceWithLogits(const Tensor& logits, const std::vector<float>& targets,
                     Tensor* dlogits) {
  const size_t n = logits.size();
  if (dlogits) dlogits->ResizeLike(logits);
  double total = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double z = logits.data[i], t = targets[i];
    // softplus(z) - z t as (1 - t) softplus(z) + t softplus(-z), each term
    // skipped at weight 0, so that an infinite logit costs 0 for the bit it
    // predicts and +inf for the other (never inf - inf = NaN).
    auto softplus = [](double x) {
      return std::max(x, 0.0) + std::log1p(std::exp(-std::abs(x)));
    };
    if (t != 1) total += (1 - t) * softplus(z);
    if (t != 0) total += t * softplus(-z);
    if (dlogits) {
      // sigmoid without overflow for either sign.
      const double e = std::exp(-std::abs(z));
      const double sigmoid = z >= 0 ? 1.0 / (1.0 + e) : e / (1.0 + e);
      dlogits->data[i] = float((sigmoid - t) / double(n));
    }
  }
  return total / double(n);
}

double MseLoss(const Tensor& a, const Tensor& b, Tensor* da) {
  const size_t n = a.size();
  if (da) da->ResizeLike(a);
  double total = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double d = double(a.data[i]) - b.data[i];
    total += d * d;
    if (da) da->data[i] = float(2.0 * d / double(n));
  }
  return total / double(n);
}

NetworkAdam::NetworkAdam(std::vector<Parameter*> params, float lr)
    : learning_rate(lr), params_(std::move(params)) {
  for (const Parameter* p : params_) {
    m.emplace_back(p->trainable ? p->size() : 0, 0.f);
    v.emplace_back(p->trainable ? p->size() : 0, 0.f);
  }
}

void NetworkAdam::ZeroGrad() {
  for (Parameter* p : params_) std::fill(p->grad.begin(), p->grad.end(), 0.f);
}

void NetworkAdam::Step() {
  constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEps = 1e-8;
  ++step;
  const double correction1 = 1.0 - std::pow(kBeta1, double(step));
  const double correction2 = 1.0 - std::pow(kBeta2, double(step));
  const float step_size = float(learning_rate / correction1);
  const float root2 = float(std::sqrt(correction2));
  for (size_t k = 0; k < params_.size(); ++k) {
    Parameter* p = params_[k];
    if (!p->trainable) continue;
    float* mk = m[k].data();
    float* vk = v[k].data();
    for (size_t i = 0; i < p->size(); ++i) {
      const float g = std::isfinite(p->grad[i]) ? p->grad[i] : 0.f;
      mk[i] = float(kBeta1) * mk[i] + float(1 - kBeta1) * g;
      vk[i] = float(kBeta2) * vk[i] + float(1 - kBeta2) * g * g;
      p->value[i] -=
          step_size * mk[i] / (std::sqrt(vk[i]) / root2 + float(kEps));
    }
  }
}

}  // namespace watergs
