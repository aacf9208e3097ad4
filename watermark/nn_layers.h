// Neural-network layers on NCHW float tensors (CPU): Conv2d, BatchNorm2d,
// ReLU, global average pooling, Linear, the BCE-with-logits and MSE losses,
// and Adam (class NetworkAdam). Layers own their parameters but not their
// activations: the caller passes the forward input back to Backward, so a
// network decides what it keeps, and a CUDA twin can offer the same calls on
// device tensors.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "watermark/tensor.h"

namespace watergs {

// A named parameter (or a buffer such as BatchNorm's running statistics).
struct Parameter {
  // Unique within a network, e.g. "decoder.block3.conv.weight".
  std::string name;
  // Logical shape, e.g. {out, in, k, k}.
  std::vector<int> shape;
  // Values and the gradient accumulated by Backward (same size).
  std::vector<float> value, grad;
  // False for buffers: saved and loaded but never optimised.
  bool trainable = true;

  Parameter() = default;
  Parameter(std::string name_, std::vector<int> shape_, bool trainable_ = true);
  size_t size() const { return value.size(); }
};

// Convolution, stride 1, zero padding kernel/2 (3x3 -> 1, 1x1 -> 0), bias.
// Computed as im2col + Eigen matrix product.
class Conv2d {
 public:
  Conv2d(const std::string& name, int in_channels, int out_channels, int kernel,
         std::mt19937* rng);
  // x [N,in,H,W] -> y [N,out,H,W].
  void Forward(const Tensor& x, Tensor* y);
  // dy [N,out,H,W] -> dx [N,in,H,W] (skipped when null); adds to the weight
  // and bias gradients when weight_grads.
  void Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                bool weight_grads);
  int in_channels() const { return in_; }
  int out_channels() const { return out_; }
  int kernel() const { return kernel_; }
  // Multiply-adds of one forward pass per output pixel.
  int64_t MacsPerPixel() const {
    return int64_t(in_) * kernel_ * kernel_ * out_;
  }

  // [out, in, k, k] and [out].
  Parameter weight, bias;

 private:
  int in_, out_, kernel_;
  // im2col workspaces, reused between calls: of x, (in*k*k) x (H*W); of dy,
  // (out*k*k) x (H*W); and the flipped kernel [in, out, k, k].
  std::vector<float> col_, dy_col_, flipped_;
};

// Batch normalisation over N, H, W per channel, as PyTorch: eps 1e-5,
// running statistics updated with momentum 0.1 (unbiased variance).
class BatchNorm2d {
 public:
  BatchNorm2d(const std::string& name, int channels);
  // training: batch statistics (and running update); else running statistics.
  void Forward(const Tensor& x, Tensor* y, bool training);
  // Gradient of the Forward call just made with the same x and mode.
  void Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                bool weight_grads, bool training);

  // gamma, beta [C]; running_mean, running_var [C] (buffers).
  Parameter gamma, beta, running_mean, running_var;
  // Running-statistics update rate (PyTorch's momentum).
  float momentum = 0.1f;
  // Added to the variance.
  float eps = 1e-5f;

 private:
  // Mean and 1/sqrt(var + eps) used by the last Forward, per channel.
  std::vector<double> mean_, invstd_;
};

// y = max(x, 0) in place.
void ReluForward(Tensor* x);
// dy *= (y > 0) in place, y the ReLU output.
void ReluBackward(const Tensor& y, Tensor* dy);

// x [N,C,H,W] -> y [N,C,1,1], the mean of each plane.
void GlobalAvgPoolForward(const Tensor& x, Tensor* y);
// dy [N,C,1,1] -> dx [N,C,H,W] with H, W given by `like`.
void GlobalAvgPoolBackward(const Tensor& dy, const Tensor& like, Tensor* dx);

// Fully connected layer on [N,in,1,1] tensors: y = W x + b.
class Linear {
 public:
  Linear(const std::string& name, int in_features, int out_features,
         std::mt19937* rng);
  // x [N,in,1,1] -> y [N,out,1,1].
  void Forward(const Tensor& x, Tensor* y) const;
  // dy [N,out,1,1] -> dx [N,in,1,1] (skipped when null).
  void Backward(const Tensor& x, const Tensor& dy, Tensor* dx,
                bool weight_grads);

  // [out, in] and [out].
  Parameter weight, bias;

 private:
  int in_, out_;
};

// Mean over all elements of the binary cross-entropy between sigmoid(logits)
// and targets in {0,1} (or [0,1]); dlogits (if not null) gets its gradient.
// Stable for any logit: (1 - t) softplus(z) + t softplus(-z); an infinite
// logit costs 0 for the bit it predicts, +inf for the other.
double BceWithLogits(const Tensor& logits, const std::vector<float>& targets,
                     Tensor* dlogits);

// rows [num_rows, row_length] (row-major): sums[r] += sum of row r, added in
// index order. Eigen's rowwise().sum() splits a row into SIMD packets by the
// row's address, so its last bits (and a training run's) varied with where
// the heap put the buffer.
void AddRowSums(const float* rows, int num_rows, size_t row_length,
                float* sums);

// Mean squared difference; da (if not null) gets d/da.
double MseLoss(const Tensor& a, const Tensor& b, Tensor* da);

// Adam with PyTorch's defaults (betas 0.9, 0.999, eps 1e-8), bias-corrected.
class NetworkAdam {
 public:
  NetworkAdam(std::vector<Parameter*> params, float learning_rate);
  // Sets every trainable gradient to zero.
  void ZeroGrad();
  // One update from the accumulated gradients.
  void Step();
  // Step size.
  float learning_rate;
  // Steps taken (for bias correction); first and second moments per param.
  int64_t step = 0;
  std::vector<std::vector<float>> m, v;
  const std::vector<Parameter*>& params() const { return params_; }

 private:
  std::vector<Parameter*> params_;
};

}  // namespace watergs
