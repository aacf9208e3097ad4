// GPU neural-network layers through cuDNN and cuBLAS (see cuda_nn.h).
#include "watermark/cuda/cuda_nn.h"

#include <algorithm>
#include <cmath>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/util/error.h"
#include "watermark/cuda/nn_kernels.h"

namespace watergs {
namespace {

const float kOne = 1.f, kZero = 0.f;

// The first usable algorithm of a _v7 result list (best first): status
// success, workspace within the limit, no TF32 unless allowed, never a
// down-converting one (ALLOW_CONVERSION computes FP32 tensors in FP16:
// overflow above 65504, underflow of small gradients, even when TF32 is
// allowed); a deterministic one when any qualifies, so repeated runs agree
// bit for bit.
template <typename Perf>
const Perf& PickAlgorithm(const std::vector<Perf>& perfs, int count,
                          bool allow_tf32, size_t limit, const char* what) {
  for (bool need_deterministic : {true, false}) {
    for (int i = 0; i < count; ++i) {
      const Perf& perf = perfs[i];
      if (perf.status != CUDNN_STATUS_SUCCESS || perf.memory > limit) continue;
      if (perf.mathType == CUDNN_TENSOR_OP_MATH_ALLOW_CONVERSION) continue;
      if (!allow_tf32 && perf.mathType == CUDNN_TENSOR_OP_MATH) continue;
      if (need_deterministic && perf.determinism != CUDNN_DETERMINISTIC)
        continue;
      return perf;
    }
  }
  Fail(std::string("cuDNN: no usable ") + what + " algorithm among " +
       std::to_string(count));
}

}  // namespace

void CudnnCheck(cudnnStatus_t status, const char* what, const char* file,
                int line) {
  if (status == CUDNN_STATUS_SUCCESS) return;
  Fail(std::string(file) + ":" + std::to_string(line) + ": cuDNN " + what +
       ": " + cudnnGetErrorString(status));
}

void CublasCheck(cublasStatus_t status, const char* what, const char* file,
                 int line) {
  if (status == CUBLAS_STATUS_SUCCESS) return;
  Fail(std::string(file) + ":" + std::to_string(line) + ": cuBLAS " + what +
       ": " + cublasGetStatusString(status));
}

CudaNnContext::CudaNnContext(bool allow_tf32) : allow_tf32_(allow_tf32) {
  WATERGS_CUDNN_CHECK(cudnnCreate(&cudnn_));
  try {
    WATERGS_CUBLAS_CHECK(cublasCreate(&cublas_));
    // FP32 GEMMs stay FP32 (no TF32) unless allowed.
    WATERGS_CUBLAS_CHECK(
        cublasSetMathMode(cublas_, allow_tf32 ? CUBLAS_TF32_TENSOR_OP_MATH
                                              : CUBLAS_DEFAULT_MATH));
  } catch (...) {
    if (cublas_) cublasDestroy(cublas_);
    cudnnDestroy(cudnn_);
    throw;
  }
}

CudaNnContext::~CudaNnContext() {
  cublasDestroy(cublas_);
  cudnnDestroy(cudnn_);
}

void* CudaNnContext::Workspace(size_t bytes) {
  if (workspace_.size() < bytes) workspace_.Resize(bytes);
  return workspace_.data();
}

void DeviceTensor::Resize(int n_, int c_, int h_, int w_) {
  n = n_, c = c_, h = h_, w = w_;
  data.Resize(size());
}

void DeviceTensor::Upload(const Tensor& host) {
  Resize(host.n, host.c, host.h, host.w);
  data.Upload(host.data);
}

void DeviceTensor::Download(Tensor* host) const {
  host->Resize(n, c, h, w);
  data.Download(&host->data);
}

CudaParameter::CudaParameter(const Parameter& host)
    : name(host.name), shape(host.shape), trainable(host.trainable) {
  value.Upload(host.value);
  if (trainable) {
    grad.Resize(host.value.size());
    grad.Zero();
  }
}

void CudaParameter::CopyToHost(Parameter* host) const {
  if (host->value.size() != value.size())
    Fail("CudaParameter " + name + ": host copy has " +
         std::to_string(host->value.size()) + " values, device " +
         std::to_string(value.size()));
  value.Download(&host->value);
  if (trainable) grad.Download(&host->grad);
}

TensorDescriptor::TensorDescriptor() {
  WATERGS_CUDNN_CHECK(cudnnCreateTensorDescriptor(&desc_));
}
TensorDescriptor::~TensorDescriptor() { cudnnDestroyTensorDescriptor(desc_); }
void TensorDescriptor::Set(int n, int c, int h, int w) {
  WATERGS_CUDNN_CHECK(cudnnSetTensor4dDescriptor(desc_, CUDNN_TENSOR_NCHW,
                                                 CUDNN_DATA_FLOAT, n, c, h, w));
}

FilterDescriptor::FilterDescriptor(int out, int in, int kernel) {
  WATERGS_CUDNN_CHECK(cudnnCreateFilterDescriptor(&desc_));
  WATERGS_CUDNN_CHECK(cudnnSetFilter4dDescriptor(
      desc_, CUDNN_DATA_FLOAT, CUDNN_TENSOR_NCHW, out, in, kernel, kernel));
}
FilterDescriptor::~FilterDescriptor() { cudnnDestroyFilterDescriptor(desc_); }

ConvolutionDescriptor::ConvolutionDescriptor(int kernel) {
  WATERGS_CUDNN_CHECK(cudnnCreateConvolutionDescriptor(&desc_));
  const int pad = kernel / 2;
  WATERGS_CUDNN_CHECK(cudnnSetConvolution2dDescriptor(
      desc_, pad, pad, 1, 1, 1, 1, CUDNN_CROSS_CORRELATION, CUDNN_DATA_FLOAT));
}
ConvolutionDescriptor::~ConvolutionDescriptor() {
  cudnnDestroyConvolutionDescriptor(desc_);
}
void ConvolutionDescriptor::SetMathType(cudnnMathType_t math) {
  WATERGS_CUDNN_CHECK(cudnnSetConvolutionMathType(desc_, math));
}

CudaConv2d::CudaConv2d(CudaNnContext* context, const Parameter& weight_,
                       const Parameter& bias_)
    : weight(weight_),
      bias(bias_),
      context_(context),
      in_(weight_.shape.size() == 4 ? weight_.shape[1] : 0),
      out_(weight_.shape.size() == 4 ? weight_.shape[0] : 0),
      kernel_(weight_.shape.size() == 4 ? weight_.shape[2] : 0),
      filter_(out_, in_, kernel_),
      conv_(kernel_) {
  if (weight_.shape.size() != 4 || weight_.shape[3] != kernel_ ||
      kernel_ % 2 != 1 || bias_.size() != size_t(out_))
    Fail("CudaConv2d " + weight_.name + ": not an [out, in, k, k] odd-k " +
         "weight with an [out] bias");
  bias_desc_.Set(1, out_, 1, 1);
}

CudaConv2d::Plan& CudaConv2d::PlanFor(const DeviceTensor& x) {
  if (x.c != in_)
    Fail("CudaConv2d " + weight.name + ": input has " + std::to_string(x.c) +
         " channels, expected " + std::to_string(in_));
  std::unique_ptr<Plan>& slot = plans_[{x.n, x.h, x.w}];
  if (slot) return *slot;
  auto plan = std::make_unique<Plan>();
  plan->x.Set(x.n, in_, x.h, x.w);
  plan->y.Set(x.n, out_, x.h, x.w);
  ChooseForward(plan.get());
  ChooseBackwardData(plan.get());
  ChooseBackwardFilter(plan.get());
  slot = std::move(plan);
  return *slot;
}

// Algorithms are queried under the math type they may use: FMA only (no
// TF32) unless the context allows TF32; each result carries the math type it
// was rated with, which is set again before each call (FMA whenever TF32 is
// not allowed). The heuristic's workspace estimate may be short, so the
// exact size is asked for too.
cudnnMathType_t CudaConv2d::QueryMath() const {
  return context_->allow_tf32() ? CUDNN_DEFAULT_MATH : CUDNN_FMA_MATH;
}

cudnnMathType_t CudaConv2d::CallMath(cudnnMathType_t rated) const {
  return context_->allow_tf32() ? rated : CUDNN_FMA_MATH;
}

void CudaConv2d::ChooseForward(Plan* plan) {
  cudnnHandle_t handle = context_->cudnn();
  int max_count = 0, count = 0;
  conv_.SetMathType(QueryMath());
  WATERGS_CUDNN_CHECK(
      cudnnGetConvolutionForwardAlgorithmMaxCount(handle, &max_count));
  std::vector<cudnnConvolutionFwdAlgoPerf_t> perfs(std::max(max_count, 1));
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionForwardAlgorithm_v7(
      handle, plan->x.get(), filter_.get(), conv_.get(), plan->y.get(),
      int(perfs.size()), &count, perfs.data()));
  const auto& best = PickAlgorithm(perfs, count, context_->allow_tf32(),
                                   context_->workspace_limit, "forward");
  plan->forward_algo = best.algo;
  plan->forward_math = CallMath(best.mathType);
  conv_.SetMathType(plan->forward_math);
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionForwardWorkspaceSize(
      handle, plan->x.get(), filter_.get(), conv_.get(), plan->y.get(),
      best.algo, &plan->forward_bytes));
  plan->forward_bytes = std::max(plan->forward_bytes, best.memory);
}

void CudaConv2d::ChooseBackwardData(Plan* plan) {
  cudnnHandle_t handle = context_->cudnn();
  int max_count = 0, count = 0;
  conv_.SetMathType(QueryMath());
  WATERGS_CUDNN_CHECK(
      cudnnGetConvolutionBackwardDataAlgorithmMaxCount(handle, &max_count));
  std::vector<cudnnConvolutionBwdDataAlgoPerf_t> perfs(std::max(max_count, 1));
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionBackwardDataAlgorithm_v7(
      handle, filter_.get(), plan->y.get(), conv_.get(), plan->x.get(),
      int(perfs.size()), &count, perfs.data()));
  const auto& best = PickAlgorithm(perfs, count, context_->allow_tf32(),
                                   context_->workspace_limit, "backward-data");
  plan->data_algo = best.algo;
  plan->data_math = CallMath(best.mathType);
  conv_.SetMathType(plan->data_math);
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionBackwardDataWorkspaceSize(
      handle, filter_.get(), plan->y.get(), conv_.get(), plan->x.get(),
      best.algo, &plan->data_bytes));
  plan->data_bytes = std::max(plan->data_bytes, best.memory);
}

void CudaConv2d::ChooseBackwardFilter(Plan* plan) {
  cudnnHandle_t handle = context_->cudnn();
  int max_count = 0, count = 0;
  conv_.SetMathType(QueryMath());
  WATERGS_CUDNN_CHECK(
      cudnnGetConvolutionBackwardFilterAlgorithmMaxCount(handle, &max_count));
  std::vector<cudnnConvolutionBwdFilterAlgoPerf_t> perfs(
      std::max(max_count, 1));
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionBackwardFilterAlgorithm_v7(
      handle, plan->x.get(), plan->y.get(), conv_.get(), filter_.get(),
      int(perfs.size()), &count, perfs.data()));
  const auto& best =
      PickAlgorithm(perfs, count, context_->allow_tf32(),
                    context_->workspace_limit, "backward-filter");
  plan->filter_algo = best.algo;
  plan->filter_math = CallMath(best.mathType);
  conv_.SetMathType(plan->filter_math);
  WATERGS_CUDNN_CHECK(cudnnGetConvolutionBackwardFilterWorkspaceSize(
      handle, plan->x.get(), plan->y.get(), conv_.get(), filter_.get(),
      best.algo, &plan->filter_bytes));
  plan->filter_bytes = std::max(plan->filter_bytes, best.memory);
}

void CudaConv2d::Forward(const DeviceTensor& x, DeviceTensor* y) {
  Plan& plan = PlanFor(x);
  y->Resize(x.n, out_, x.h, x.w);
  conv_.SetMathType(plan.forward_math);
  void* workspace = context_->Workspace(plan.forward_bytes);
  WATERGS_CUDNN_CHECK(cudnnConvolutionForward(
      context_->cudnn(), &kOne, plan.x.get(), x.ptr(), filter_.get(),
      weight.value.data(), conv_.get(), plan.forward_algo, workspace,
      plan.forward_bytes, &kZero, plan.y.get(), y->ptr()));
  WATERGS_CUDNN_CHECK(cudnnAddTensor(context_->cudnn(), &kOne, bias_desc_.get(),
                                     bias.value.data(), &kOne, plan.y.get(),
                                     y->ptr()));
}

void CudaConv2d::Backward(const DeviceTensor& x, const DeviceTensor& dy,
                          DeviceTensor* dx, bool weight_grads) {
  Plan& plan = PlanFor(x);
  if (dy.n != x.n || dy.c != out_ || dy.h != x.h || dy.w != x.w)
    Fail("CudaConv2d " + weight.name + ": output gradient shape mismatch");
  if (weight_grads) {
    conv_.SetMathType(plan.filter_math);
    void* workspace = context_->Workspace(plan.filter_bytes);
    // beta = 1: gradients accumulate, as the CPU layer's do.
    WATERGS_CUDNN_CHECK(cudnnConvolutionBackwardFilter(
        context_->cudnn(), &kOne, plan.x.get(), x.ptr(), plan.y.get(), dy.ptr(),
        conv_.get(), plan.filter_algo, workspace, plan.filter_bytes, &kOne,
        filter_.get(), weight.grad.data()));
    WATERGS_CUDNN_CHECK(cudnnConvolutionBackwardBias(
        context_->cudnn(), &kOne, plan.y.get(), dy.ptr(), &kOne,
        bias_desc_.get(), bias.grad.data()));
  }
  if (!dx) return;
  dx->ResizeLike(x);
  conv_.SetMathType(plan.data_math);
  void* workspace = context_->Workspace(plan.data_bytes);
  WATERGS_CUDNN_CHECK(cudnnConvolutionBackwardData(
      context_->cudnn(), &kOne, filter_.get(), weight.value.data(),
      plan.y.get(), dy.ptr(), conv_.get(), plan.data_algo, workspace,
      plan.data_bytes, &kZero, plan.x.get(), dx->ptr()));
}

CudaBatchNorm2d::CudaBatchNorm2d(CudaNnContext* context,
                                 const Parameter& gamma_,
                                 const Parameter& beta_,
                                 const Parameter& running_mean_,
                                 const Parameter& running_var_, float momentum_,
                                 float eps_)
    : gamma(gamma_),
      beta(beta_),
      running_mean(running_mean_),
      running_var(running_var_),
      momentum(momentum_),
      eps(eps_),
      context_(context),
      channels_(int(gamma_.size())) {
  if (beta_.size() != gamma_.size() || running_mean_.size() != gamma_.size() ||
      running_var_.size() != gamma_.size())
    Fail("CudaBatchNorm2d " + gamma_.name + ": parameters of unequal sizes");
  // cuDNN refuses a smaller epsilon; the CPU default (1e-5) is allowed.
  if (double(eps_) < CUDNN_BN_MIN_EPSILON)
    Fail("CudaBatchNorm2d " + gamma_.name + ": eps below cuDNN's minimum");
  param_desc_.Set(1, channels_, 1, 1);
  save_mean_.Resize(channels_);
  save_invstd_.Resize(channels_);
  scratch_dgamma_.Resize(channels_);
  scratch_dbeta_.Resize(channels_);
}

void CudaBatchNorm2d::Forward(const DeviceTensor& x, DeviceTensor* y,
                              bool training) {
  if (x.c != channels_)
    Fail("CudaBatchNorm2d " + gamma.name + ": input has " +
         std::to_string(x.c) + " channels, expected " +
         std::to_string(channels_));
  y->ResizeLike(x);
  x_desc_.Set(x.n, x.c, x.h, x.w);
  if (!training) {
    WATERGS_CUDNN_CHECK(cudnnBatchNormalizationForwardInference(
        context_->cudnn(), CUDNN_BATCHNORM_SPATIAL, &kOne, &kZero,
        x_desc_.get(), x.ptr(), x_desc_.get(), y->ptr(), param_desc_.get(),
        gamma.value.data(), beta.value.data(), running_mean.value.data(),
        running_var.value.data(), double(eps)));
    return;
  }
  if (x.size() / size_t(channels_) < 2)
    Fail("CudaBatchNorm2d " + gamma.name +
         ": training needs more than one value per channel");
  // Running statistics first, from x, with the CPU's formula (see the
  // header); cuDNN only normalises and saves mean and 1/sqrt(var + eps).
  WATERGS_CUDA_CHECK(nn_kernels::BatchNormRunningUpdate(
      x.ptr(), x.n, x.c, x.PlaneSize(), momentum, running_mean.value.data(),
      running_var.value.data()));
  WATERGS_CUDNN_CHECK(cudnnBatchNormalizationForwardTraining(
      context_->cudnn(), CUDNN_BATCHNORM_SPATIAL, &kOne, &kZero, x_desc_.get(),
      x.ptr(), x_desc_.get(), y->ptr(), param_desc_.get(), gamma.value.data(),
      beta.value.data(), 0.0, nullptr, nullptr, double(eps), save_mean_.data(),
      save_invstd_.data()));
}

void CudaBatchNorm2d::Backward(const DeviceTensor& x, const DeviceTensor& dy,
                               DeviceTensor* dx, bool weight_grads,
                               bool training) {
  const size_t hw = x.PlaneSize();
  if (!training) {
    // Inference mode: an affine map per channel, no batch coupling.
    if (weight_grads)
      WATERGS_CUDA_CHECK(nn_kernels::BatchNormInferenceParamGrads(
          x.ptr(), dy.ptr(), running_mean.value.data(),
          running_var.value.data(), eps, x.n, x.c, hw, gamma.grad.data(),
          beta.grad.data()));
    if (!dx) return;
    dx->ResizeLike(x);
    WATERGS_CUDA_CHECK(nn_kernels::BatchNormInferenceBackwardData(
        dy.ptr(), gamma.value.data(), running_var.value.data(), eps, x.n, x.c,
        hw, dx->ptr()));
    return;
  }
  DeviceTensor* out = dx ? dx : &scratch_dx_;
  out->ResizeLike(x);
  x_desc_.Set(x.n, x.c, x.h, x.w);
  // Parameter gradients accumulate (beta 1) or go to scratch.
  const float* param_blend = weight_grads ? &kOne : &kZero;
  WATERGS_CUDNN_CHECK(cudnnBatchNormalizationBackward(
      context_->cudnn(), CUDNN_BATCHNORM_SPATIAL, &kOne, &kZero, &kOne,
      param_blend, x_desc_.get(), x.ptr(), x_desc_.get(), dy.ptr(),
      x_desc_.get(), out->ptr(), param_desc_.get(), gamma.value.data(),
      weight_grads ? gamma.grad.data() : scratch_dgamma_.data(),
      weight_grads ? beta.grad.data() : scratch_dbeta_.data(), double(eps),
      save_mean_.data(), save_invstd_.data()));
}

void CudaReluForward(DeviceTensor* x) {
  WATERGS_CUDA_CHECK(nn_kernels::ReluForward(x->ptr(), x->size()));
}

void CudaReluBackward(const DeviceTensor& y, DeviceTensor* dy) {
  WATERGS_CUDA_CHECK(nn_kernels::ReluBackward(y.ptr(), dy->ptr(), y.size()));
}

void CudaGlobalAvgPoolForward(const DeviceTensor& x, DeviceTensor* y) {
  y->Resize(x.n, x.c, 1, 1);
  WATERGS_CUDA_CHECK(nn_kernels::GlobalAvgPoolForward(x.ptr(), x.n * x.c,
                                                      x.PlaneSize(), y->ptr()));
}

void CudaGlobalAvgPoolBackward(const DeviceTensor& dy, const DeviceTensor& like,
                               DeviceTensor* dx) {
  dx->ResizeLike(like);
  WATERGS_CUDA_CHECK(nn_kernels::GlobalAvgPoolBackward(
      dy.ptr(), like.n * like.c, like.PlaneSize(), dx->ptr()));
}

CudaLinear::CudaLinear(CudaNnContext* context, const Parameter& weight_,
                       const Parameter& bias_)
    : weight(weight_),
      bias(bias_),
      context_(context),
      in_(weight_.shape.size() == 2 ? weight_.shape[1] : 0),
      out_(weight_.shape.size() == 2 ? weight_.shape[0] : 0) {
  if (weight_.shape.size() != 2 || bias_.size() != size_t(out_))
    Fail("CudaLinear " + weight_.name + ": not an [out, in] weight with an " +
         "[out] bias");
}

// Row-major [N, in] / [out, in] / [N, out] matrices are column-major
// [in, N] / [in, out] / [out, N] ones to cuBLAS, hence the transposes below.
void CudaLinear::Forward(const DeviceTensor& x, DeviceTensor* y) {
  if (x.c * x.h * x.w != in_)
    Fail("CudaLinear " + weight.name + ": input of " +
         std::to_string(x.c * x.h * x.w) + " features, expected " +
         std::to_string(in_));
  y->Resize(x.n, out_, 1, 1);
  WATERGS_CUDA_CHECK(
      nn_kernels::BroadcastRows(bias.value.data(), x.n, out_, y->ptr()));
  // Y^T [out, N] += W [out, in] X^T [in, N].
  WATERGS_CUBLAS_CHECK(cublasSgemm(context_->cublas(), CUBLAS_OP_T, CUBLAS_OP_N,
                                   out_, x.n, in_, &kOne, weight.value.data(),
                                   in_, x.ptr(), in_, &kOne, y->ptr(), out_));
}

void CudaLinear::Backward(const DeviceTensor& x, const DeviceTensor& dy,
                          DeviceTensor* dx, bool weight_grads) {
  // cuBLAS reads x.n rows of each: a mismatch would read past the buffers.
  if (x.c * x.h * x.w != in_ || dy.n != x.n || dy.c * dy.h * dy.w != out_)
    Fail("CudaLinear " + weight.name + ": input or output gradient shape " +
         "mismatch");
  if (dx) {
    dx->ResizeLike(x);
    // dX^T [in, N] = W^T [in, out] dY^T [out, N].
    WATERGS_CUBLAS_CHECK(cublasSgemm(
        context_->cublas(), CUBLAS_OP_N, CUBLAS_OP_N, in_, x.n, out_, &kOne,
        weight.value.data(), in_, dy.ptr(), out_, &kZero, dx->ptr(), in_));
  }
  if (!weight_grads) return;
  // dW^T [in, out] += X^T [in, N] dY [N, out].
  WATERGS_CUBLAS_CHECK(cublasSgemm(
      context_->cublas(), CUBLAS_OP_N, CUBLAS_OP_T, in_, out_, x.n, &kOne,
      x.ptr(), in_, dy.ptr(), out_, &kOne, weight.grad.data(), in_));
  WATERGS_CUDA_CHECK(
      nn_kernels::AddColumnSums(dy.ptr(), x.n, out_, bias.grad.data()));
}

double CudaBceWithLogits(const DeviceTensor& logits,
                         const DeviceBuffer<float>& targets,
                         DeviceTensor* dlogits) {
  if (targets.size() != logits.size())
    Fail("CudaBceWithLogits: " + std::to_string(targets.size()) +
         " targets for " + std::to_string(logits.size()) + " logits");
  if (dlogits) dlogits->ResizeLike(logits);
  DeviceBuffer<double> loss(1);
  WATERGS_CUDA_CHECK(nn_kernels::BceWithLogits(
      logits.ptr(), targets.data(), logits.size(), loss.data(),
      dlogits ? dlogits->ptr() : nullptr));
  std::vector<double> host;
  loss.Download(&host);
  return host[0];
}

double CudaAddMseGradient(const DeviceTensor& a, const DeviceTensor& b,
                          float weight, DeviceTensor* grad) {
  if (a.size() != b.size() || (grad && grad->size() != a.size()))
    Fail("CudaMseLoss: tensors of different sizes");
  DeviceBuffer<double> loss(1);
  WATERGS_CUDA_CHECK(nn_kernels::MseLoss(a.ptr(), b.ptr(), a.size(), weight,
                                         loss.data(),
                                         grad ? grad->ptr() : nullptr));
  std::vector<double> host;
  loss.Download(&host);
  return host[0];
}

double CudaMseLoss(const DeviceTensor& a, const DeviceTensor& b,
                   DeviceTensor* da) {
  if (da) {
    da->ResizeLike(a);
    da->data.Zero();
  }
  return CudaAddMseGradient(a, b, 1.f, da);
}

CudaNetworkAdam::CudaNetworkAdam(std::vector<CudaParameter*> params, float lr)
    : learning_rate(lr), params_(std::move(params)) {
  for (const CudaParameter* p : params_) {
    const size_t n = p->trainable ? p->size() : 0;
    m.emplace_back(n);
    v.emplace_back(n);
    m.back().Zero();
    v.back().Zero();
  }
}

void CudaNetworkAdam::ZeroGrad() {
  for (CudaParameter* p : params_) p->grad.Zero();
}

void CudaNetworkAdam::Step() {
  // The CPU's constants, computed the same way (double, then float).
  constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEps = 1e-8;
  ++step;
  const double correction1 = 1.0 - std::pow(kBeta1, double(step));
  const double correction2 = 1.0 - std::pow(kBeta2, double(step));
  nn_kernels::AdamConstants k;
  k.beta1 = float(kBeta1);
  k.one_minus_beta1 = float(1 - kBeta1);
  k.beta2 = float(kBeta2);
  k.one_minus_beta2 = float(1 - kBeta2);
  k.eps = float(kEps);
  k.step_size = float(learning_rate / correction1);
  k.root2 = float(std::sqrt(correction2));
  for (size_t i = 0; i < params_.size(); ++i) {
    CudaParameter* p = params_[i];
    if (!p->trainable) continue;
    WATERGS_CUDA_CHECK(nn_kernels::AdamStep(p->value.data(), p->grad.data(),
                                            m[i].data(), v[i].data(), p->size(),
                                            k));
  }
}

void CudaNetworkAdam::CopyFrom(const NetworkAdam& host) {
  if (host.m.size() != params_.size())
    Fail("CudaNetworkAdam: the host optimiser has " +
         std::to_string(host.m.size()) + " parameters, the device one " +
         std::to_string(params_.size()));
  for (size_t i = 0; i < params_.size(); ++i) {
    if (host.m[i].size() != m[i].size() || host.v[i].size() != v[i].size())
      Fail("CudaNetworkAdam: moments of " + params_[i]->name +
           " differ in size");
    m[i].Upload(host.m[i]);
    v[i].Upload(host.v[i]);
  }
  learning_rate = host.learning_rate;
  step = host.step;
}

void CudaNetworkAdam::CopyToHost(NetworkAdam* host) const {
  if (host->m.size() != params_.size())
    Fail("CudaNetworkAdam: the host optimiser has " +
         std::to_string(host->m.size()) + " parameters, the device one " +
         std::to_string(params_.size()));
  for (size_t i = 0; i < params_.size(); ++i) {
    m[i].Download(&host->m[i]);
    v[i].Download(&host->v[i]);
  }
  host->learning_rate = learning_rate;
  host->step = step;
}

}  // namespace watergs
