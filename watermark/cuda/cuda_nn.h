// The neural-network layers of nn_layers.h on the GPU: the same calls
// (Forward, Backward with the forward input passed back, weight gradients
// accumulated into Parameter-like buffers) on device tensors, with
// convolutions through cuDNN (forward, backward-data, backward-filter,
// backward-bias), BatchNorm through cuDNN plus our own kernel for the running
// statistics, Linear through cuBLAS, and the rest as small kernels
// (nn_kernels.h). Parity with the CPU layers is tested in
// tests/watermark/cuda_nn_test.cc.
//
// Numerics: convolutions use FP32 FMA math only (no TF32 tensor cores)
// unless the context allows TF32, so results match the CPU to float
// rounding. BatchNorm's running statistics are not cuDNN's: cuDNN gets null
// running-stat pointers and a kernel updates them with the CPU's exact
// formula (two-pass double mean and variance, unbiased N/(N-1) variance,
// momentum 0.1), so PyTorch semantics hold whatever cuDNN's convention is.
#pragma once

#include <cublas_v2.h>
#include <cudnn.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/cuda/device_buffer.h"
#include "watermark/nn_layers.h"

namespace watergs {

// Throw Error("<file>:<line>: cuDNN|cuBLAS <call>: <message>") unless ok.
void CudnnCheck(cudnnStatus_t status, const char* what, const char* file,
                int line);
void CublasCheck(cublasStatus_t status, const char* what, const char* file,
                 int line);

}  // namespace watergs

#define WATERGS_CUDNN_CHECK(call) \
  ::watergs::CudnnCheck((call), #call, __FILE__, __LINE__)
#define WATERGS_CUBLAS_CHECK(call) \
  ::watergs::CublasCheck((call), #call, __FILE__, __LINE__)

namespace watergs {

// The cuDNN and cuBLAS handles and the one convolution workspace shared by
// every layer built on this context. Not thread-safe; default stream.
class CudaNnContext {
 public:
  // allow_tf32: let cuDNN pick TF32 tensor-core algorithms (faster, ~1e-3
  // relative error); parity tests use false.
  explicit CudaNnContext(bool allow_tf32 = false);
  ~CudaNnContext();
  CudaNnContext(const CudaNnContext&) = delete;
  CudaNnContext& operator=(const CudaNnContext&) = delete;

  cudnnHandle_t cudnn() const { return cudnn_; }
  cublasHandle_t cublas() const { return cublas_; }
  bool allow_tf32() const { return allow_tf32_; }
  // Device scratch of at least `bytes` (grown, never shrunk); valid until
  // the next call.
  void* Workspace(size_t bytes);
  // Algorithms needing more workspace than this are not chosen.
  size_t workspace_limit = size_t(1) << 30;

 private:
  // Owned handles (default stream).
  cudnnHandle_t cudnn_ = nullptr;
  cublasHandle_t cublas_ = nullptr;
  // Whether TF32 tensor-core math may be used.
  bool allow_tf32_;
  // The shared convolution workspace.
  DeviceBuffer<unsigned char> workspace_;
};

// An NCHW float tensor in device memory (the twin of Tensor).
struct DeviceTensor {
  // Batch, channels, height, width.
  int n = 0, c = 0, h = 0, w = 0;
  // n * c * h * w values, NCHW.
  DeviceBuffer<float> data;

  DeviceTensor() = default;
  DeviceTensor(int n_, int c_, int h_, int w_) { Resize(n_, c_, h_, w_); }
  // Sets the shape; reallocates only on growth (values then unspecified).
  void Resize(int n_, int c_, int h_, int w_);
  void ResizeLike(const DeviceTensor& other) {
    Resize(other.n, other.c, other.h, other.w);
  }
  size_t size() const { return size_t(n) * c * h * w; }
  size_t PlaneSize() const { return size_t(h) * w; }
  float* ptr() { return data.data(); }
  const float* ptr() const { return data.data(); }
  // Host tensor -> device (shape and values), and back.
  void Upload(const Tensor& host);
  void Download(Tensor* host) const;
};

// A Parameter's value and gradient on the device.
struct CudaParameter {
  // As the host Parameter.
  std::string name;
  std::vector<int> shape;
  bool trainable = true;
  // Values and accumulated gradient (empty for buffers).
  DeviceBuffer<float> value, grad;

  // Copies host.value; the gradient starts at zero.
  explicit CudaParameter(const Parameter& host);
  size_t size() const { return value.size(); }
  // Writes value (and grad when trainable) into `host` (same shape).
  void CopyToHost(Parameter* host) const;
};

// RAII cuDNN descriptors.
class TensorDescriptor {
 public:
  TensorDescriptor();
  ~TensorDescriptor();
  TensorDescriptor(const TensorDescriptor&) = delete;
  TensorDescriptor& operator=(const TensorDescriptor&) = delete;
  // NCHW float.
  void Set(int n, int c, int h, int w);
  cudnnTensorDescriptor_t get() const { return desc_; }

 private:
  cudnnTensorDescriptor_t desc_ = nullptr;
};

class FilterDescriptor {
 public:
  // [out, in, k, k] float.
  FilterDescriptor(int out, int in, int kernel);
  ~FilterDescriptor();
  FilterDescriptor(const FilterDescriptor&) = delete;
  FilterDescriptor& operator=(const FilterDescriptor&) = delete;
  cudnnFilterDescriptor_t get() const { return desc_; }

 private:
  cudnnFilterDescriptor_t desc_ = nullptr;
};

class ConvolutionDescriptor {
 public:
  // Stride 1, padding kernel / 2, cross-correlation (as Conv2d), FP32.
  explicit ConvolutionDescriptor(int kernel);
  ~ConvolutionDescriptor();
  ConvolutionDescriptor(const ConvolutionDescriptor&) = delete;
  ConvolutionDescriptor& operator=(const ConvolutionDescriptor&) = delete;
  void SetMathType(cudnnMathType_t math);
  cudnnConvolutionDescriptor_t get() const { return desc_; }

 private:
  cudnnConvolutionDescriptor_t desc_ = nullptr;
};

// Conv2d (stride 1, zero padding k/2, bias) through cuDNN.
class CudaConv2d {
 public:
  // weight [out, in, k, k] and bias [out] copied from the host.
  CudaConv2d(CudaNnContext* context, const Parameter& weight,
             const Parameter& bias);
  CudaConv2d(CudaNnContext* context, const Conv2d& cpu)
      : CudaConv2d(context, cpu.weight, cpu.bias) {}
  // x [N,in,H,W] -> y [N,out,H,W].
  void Forward(const DeviceTensor& x, DeviceTensor* y);
  // dy [N,out,H,W] -> dx [N,in,H,W] (skipped when null); adds to the weight
  // and bias gradients when weight_grads.
  void Backward(const DeviceTensor& x, const DeviceTensor& dy, DeviceTensor* dx,
                bool weight_grads);
  int in_channels() const { return in_; }
  int out_channels() const { return out_; }
  int kernel() const { return kernel_; }

  // [out, in, k, k] and [out].
  CudaParameter weight, bias;

 private:
  // Descriptors and chosen algorithms for one input shape.
  struct Plan {
    // Input [N,in,H,W] and output [N,out,H,W].
    TensorDescriptor x, y;
    cudnnConvolutionFwdAlgo_t forward_algo;
    cudnnConvolutionBwdDataAlgo_t data_algo;
    cudnnConvolutionBwdFilterAlgo_t filter_algo;
    // Math type each algorithm was chosen with (set before each call).
    cudnnMathType_t forward_math, data_math, filter_math;
    // Workspace bytes of each algorithm.
    size_t forward_bytes = 0, data_bytes = 0, filter_bytes = 0;
  };
  // The plan for x's shape, made (algorithms chosen) on first use.
  Plan& PlanFor(const DeviceTensor& x);
  // Each direction's algorithm, math type and workspace size for a plan.
  void ChooseForward(Plan* plan);
  void ChooseBackwardData(Plan* plan);
  void ChooseBackwardFilter(Plan* plan);
  // Math type to query algorithms under, and to run one rated `rated` with.
  cudnnMathType_t QueryMath() const;
  cudnnMathType_t CallMath(cudnnMathType_t rated) const;

  // Handles and workspace (not owned); layer shape.
  CudaNnContext* context_;
  int in_, out_, kernel_;
  FilterDescriptor filter_;
  ConvolutionDescriptor conv_;
  // [1, out, 1, 1] for the bias.
  TensorDescriptor bias_desc_;
  // Plans by (N, H, W).
  std::map<std::array<int, 3>, std::unique_ptr<Plan>> plans_;
};

// BatchNorm2d (PyTorch semantics, see the file comment) through cuDNN's
// spatial batch normalisation.
class CudaBatchNorm2d {
 public:
  CudaBatchNorm2d(CudaNnContext* context, const Parameter& gamma,
                  const Parameter& beta, const Parameter& running_mean,
                  const Parameter& running_var, float momentum, float eps);
  CudaBatchNorm2d(CudaNnContext* context, const BatchNorm2d& cpu)
      : CudaBatchNorm2d(context, cpu.gamma, cpu.beta, cpu.running_mean,
                        cpu.running_var, cpu.momentum, cpu.eps) {}
  // training: batch statistics (and running update); else running ones.
  // Training needs more than one value per channel (N * H * W > 1).
  void Forward(const DeviceTensor& x, DeviceTensor* y, bool training);
  // Gradient of the Forward call just made with the same x and mode.
  void Backward(const DeviceTensor& x, const DeviceTensor& dy, DeviceTensor* dx,
                bool weight_grads, bool training);

  // gamma, beta [C]; running_mean, running_var [C] (buffers).
  CudaParameter gamma, beta, running_mean, running_var;
  float momentum, eps;

 private:
  // Handles (not owned); number of channels.
  CudaNnContext* context_;
  int channels_;
  // x's shape, and [1, C, 1, 1] for the per-channel tensors.
  TensorDescriptor x_desc_, param_desc_;
  // Batch mean and 1/sqrt(var + eps) saved by cuDNN's training forward.
  DeviceBuffer<float> save_mean_, save_invstd_;
  // Sinks for cuDNN's parameter gradients when they are not wanted, and for
  // its input gradient when dx is null.
  DeviceBuffer<float> scratch_dgamma_, scratch_dbeta_;
  DeviceTensor scratch_dx_;
};

// y = max(x, 0) in place.
void CudaReluForward(DeviceTensor* x);
// dy *= (y > 0) in place, y the ReLU output.
void CudaReluBackward(const DeviceTensor& y, DeviceTensor* dy);
// x [N,C,H,W] -> y [N,C,1,1], the mean of each plane.
void CudaGlobalAvgPoolForward(const DeviceTensor& x, DeviceTensor* y);
// dy [N,C,1,1] -> dx [N,C,H,W] with H, W given by `like`.
void CudaGlobalAvgPoolBackward(const DeviceTensor& dy, const DeviceTensor& like,
                               DeviceTensor* dx);

// Linear (y = W x + b on [N,in,1,1]) through cuBLAS.
class CudaLinear {
 public:
  CudaLinear(CudaNnContext* context, const Parameter& weight,
             const Parameter& bias);
  CudaLinear(CudaNnContext* context, const Linear& cpu)
      : CudaLinear(context, cpu.weight, cpu.bias) {}
  // x [N,in,1,1] -> y [N,out,1,1].
  void Forward(const DeviceTensor& x, DeviceTensor* y);
  // dy [N,out,1,1] -> dx [N,in,1,1] (skipped when null).
  void Backward(const DeviceTensor& x, const DeviceTensor& dy, DeviceTensor* dx,
                bool weight_grads);

  // [out, in] and [out].
  CudaParameter weight, bias;

 private:
  // Handles (not owned); features in and out.
  CudaNnContext* context_;
  int in_, out_;
};

// Mean BCE between sigmoid(logits) and targets (device, logits.size()
// values 0/1 or in [0,1]); dlogits (if not null) gets its gradient. Same
// stable form as BceWithLogits. Synchronises (returns the loss).
double CudaBceWithLogits(const DeviceTensor& logits,
                         const DeviceBuffer<float>& targets,
                         DeviceTensor* dlogits);
// Mean squared difference; da (if not null) gets d/da. Synchronises.
double CudaMseLoss(const DeviceTensor& a, const DeviceTensor& b,
                   DeviceTensor* da);
// As CudaMseLoss, but grad += weight * d/da (grad shaped like a).
double CudaAddMseGradient(const DeviceTensor& a, const DeviceTensor& b,
                          float weight, DeviceTensor* grad);

// NetworkAdam on device parameters: same defaults, same bias correction.
// (Not "CudaAdam": gaussian/cuda/cuda_adam.h owns watergs::CudaAdam, the
// Gaussian-parameter optimiser; two classes of one name in two libraries of
// one program break the one-definition rule.)
class CudaNetworkAdam {
 public:
  CudaNetworkAdam(std::vector<CudaParameter*> params, float learning_rate);
  // Sets every trainable gradient to zero.
  void ZeroGrad();
  // One update from the accumulated gradients.
  void Step();
  // Learning rate, step count and moments from / to a NetworkAdam over the
  // same parameters in the same order (checkpoints, resume, validation).
  void CopyFrom(const NetworkAdam& host);
  void CopyToHost(NetworkAdam* host) const;
  // Step size.
  float learning_rate;
  // Steps taken (for bias correction); first and second moments per param.
  int64_t step = 0;
  std::vector<DeviceBuffer<float>> m, v;

 private:
  // The optimised parameters (not owned), in moment order.
  std::vector<CudaParameter*> params_;
};

}  // namespace watergs
