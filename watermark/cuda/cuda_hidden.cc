// HiDDeN networks and the frozen decoder on the GPU (see cuda_hidden.h).
// Each function follows its CPU twin in hidden_net.cc / decoder.cc line by
// line, so a parity mismatch points at one layer.
#include "watermark/cuda/cuda_hidden.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "gaussian/cuda/cuda_check.h"
#include "gaussian/util/error.h"
#include "watermark/cuda/nn_kernels.h"

namespace watergs {
namespace {

// Parameters per ConvBnRelu block (conv weight/bias, BN gamma/beta/running
// mean/running var).
constexpr size_t kBlockParameters = 6;

// all[begin, begin + count), checked against the CPU network's layout.
std::vector<Parameter*> Slice(const std::vector<Parameter*>& all, size_t begin,
                              size_t count, const std::string& what) {
  if (begin + count > all.size())
    Fail(what + ": the CPU network has " + std::to_string(all.size()) +
         " parameters, fewer than its architecture implies");
  return std::vector<Parameter*>(all.begin() + begin,
                                 all.begin() + begin + count);
}

// The checked parameters of one block.
const std::vector<Parameter*>& CheckBlock(const std::vector<Parameter*>& p) {
  static const char* const kSuffixes[kBlockParameters] = {
      ".conv.weight", ".conv.bias",       ".bn.weight",
      ".bn.bias",     ".bn.running_mean", ".bn.running_var"};
  if (p.size() != kBlockParameters)
    Fail("CudaConvBnRelu: " + std::to_string(p.size()) + " parameters, not 6");
  for (size_t i = 0; i < kBlockParameters; ++i) {
    const std::string& name = p[i]->name;
    const std::string suffix = kSuffixes[i];
    if (name.size() < suffix.size() ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
      Fail("CudaConvBnRelu: parameter " + name + " where *" + suffix +
           " was expected");
  }
  return p;
}

// BatchNorm2d's defaults (the CPU blocks never change them).
const BatchNorm2d& DefaultBatchNorm() {
  static const BatchNorm2d defaults("defaults", 1);
  return defaults;
}

}  // namespace

CudaConvBnRelu::CudaConvBnRelu(CudaNnContext* context,
                               const std::vector<Parameter*>& params)
    : conv(context, *CheckBlock(params)[0], *params[1]),
      bn(context, *params[2], *params[3], *params[4], *params[5],
         DefaultBatchNorm().momentum, DefaultBatchNorm().eps) {}

void CudaConvBnRelu::Forward(const DeviceTensor& x, bool training) {
  conv.Forward(x, &conv_out_);
  bn.Forward(conv_out_, &out_, training);
  CudaReluForward(&out_);
}

void CudaConvBnRelu::Backward(const DeviceTensor& x, DeviceTensor* dout,
                              DeviceTensor* dx, bool weight_grads,
                              bool training) {
  CudaReluBackward(out_, dout);
  bn.Backward(conv_out_, *dout, &dconv_, weight_grads, training);
  conv.Backward(x, dconv_, dx, weight_grads);
}

void CudaConvBnRelu::CollectParameters(std::vector<CudaParameter*>* out) {
  for (CudaParameter* p : {&conv.weight, &conv.bias, &bn.gamma, &bn.beta,
                           &bn.running_mean, &bn.running_var})
    out->push_back(p);
}

CudaHiddenDecoder::CudaHiddenDecoder(CudaNnContext* context,
                                     const HiddenConfig& config,
                                     HiddenDecoder& cpu)
    : config_(config) {
  std::vector<Parameter*> params;
  cpu.CollectParameters(&params);
  const size_t blocks = size_t(config.decoder_blocks) + 1;
  if (cpu.num_bits() != config.num_bits ||
      params.size() != blocks * kBlockParameters + 2)
    Fail("CudaHiddenDecoder: the CPU decoder does not match its config");
  for (size_t i = 0; i < blocks; ++i)
    blocks_.push_back(std::make_unique<CudaConvBnRelu>(
        context, Slice(params, i * kBlockParameters, kBlockParameters,
                       "CudaHiddenDecoder")));
  linear_ = std::make_unique<CudaLinear>(context, *params[params.size() - 2],
                                         *params.back());
}

const DeviceTensor& CudaHiddenDecoder::Forward(const DeviceTensor& image,
                                               bool training) {
  image_ = &image;
  const DeviceTensor* x = &image;
  for (auto& block : blocks_) {
    block->Forward(*x, training);
    x = &block->output();
  }
  CudaGlobalAvgPoolForward(*x, &pooled_);
  linear_->Forward(pooled_, &logits_);
  return logits_;
}

void CudaHiddenDecoder::Backward(const DeviceTensor& dlogits,
                                 DeviceTensor* dimage, bool weight_grads,
                                 bool training) {
  linear_->Backward(pooled_, dlogits, &dpooled_, weight_grads);
  CudaGlobalAvgPoolBackward(dpooled_, blocks_.back()->output(), &da_);
  for (int i = int(blocks_.size()) - 1; i >= 0; --i) {
    const DeviceTensor& input = i == 0 ? *image_ : blocks_[i - 1]->output();
    DeviceTensor* dx = i == 0 ? dimage : &db_;
    if (i == 0 && !dimage && !weight_grads) break;
    blocks_[i]->Backward(input, &da_, dx, weight_grads, training);
    std::swap(da_, db_);
  }
}

void CudaHiddenDecoder::CollectParameters(std::vector<CudaParameter*>* out) {
  for (auto& block : blocks_) block->CollectParameters(out);
  out->push_back(&linear_->weight);
  out->push_back(&linear_->bias);
}

CudaHiddenEncoder::CudaHiddenEncoder(CudaNnContext* context,
                                     const HiddenConfig& config,
                                     HiddenEncoder& cpu)
    : config_(config) {
  std::vector<Parameter*> params;
  cpu.CollectParameters(&params);
  const size_t blocks = size_t(config.encoder_blocks);
  if (params.size() != (blocks + 1) * kBlockParameters + 2)
    Fail("CudaHiddenEncoder: the CPU encoder does not match its config");
  for (size_t i = 0; i < blocks; ++i)
    blocks_.push_back(std::make_unique<CudaConvBnRelu>(
        context, Slice(params, i * kBlockParameters, kBlockParameters,
                       "CudaHiddenEncoder")));
  after_concat_ = std::make_unique<CudaConvBnRelu>(
      context, Slice(params, blocks * kBlockParameters, kBlockParameters,
                     "CudaHiddenEncoder"));
  final_ = std::make_unique<CudaConv2d>(context, *params[params.size() - 2],
                                        *params.back());
}

const DeviceTensor& CudaHiddenEncoder::Forward(
    const DeviceTensor& cover, const DeviceBuffer<float>& message,
    bool training) {
  const int bits = config_.num_bits, ch = config_.channels;
  if (message.size() != size_t(cover.n) * bits)
    Fail("CudaHiddenEncoder: " + std::to_string(message.size()) +
         " message values for " + std::to_string(cover.n) + " images of " +
         std::to_string(bits) + " bits");
  cover_ = &cover;
  const DeviceTensor* x = &cover;
  for (auto& block : blocks_) {
    block->Forward(*x, training);
    x = &block->output();
  }
  const int total = bits + ch + 3;
  const size_t hw = cover.PlaneSize();
  concat_.Resize(cover.n, total, cover.h, cover.w);
  WATERGS_CUDA_CHECK(nn_kernels::FillMessagePlanes(
      message.data(), cover.n, bits, hw, concat_.ptr(), total));
  WATERGS_CUDA_CHECK(nn_kernels::CopyChannels(x->ptr(), cover.n, ch, 0, ch, hw,
                                              concat_.ptr(), total, bits));
  WATERGS_CUDA_CHECK(nn_kernels::CopyChannels(cover.ptr(), cover.n, 3, 0, 3, hw,
                                              concat_.ptr(), total, bits + ch));
  after_concat_->Forward(concat_, training);
  final_->Forward(after_concat_->output(), &residual_);
  watermarked_.ResizeLike(cover);
  WATERGS_CUDA_CHECK(nn_kernels::Add(cover.ptr(), residual_.ptr(), cover.size(),
                                     watermarked_.ptr()));
  return watermarked_;
}

void CudaHiddenEncoder::Backward(const DeviceTensor& dwatermarked,
                                 bool training) {
  // d residual = d watermarked.
  final_->Backward(after_concat_->output(), dwatermarked, &dblock_, true);
  after_concat_->Backward(concat_, &dblock_, &dconcat_, true, training);
  const int bits = config_.num_bits, ch = config_.channels;
  const DeviceTensor& cover = *cover_;
  dblock_.Resize(cover.n, ch, cover.h, cover.w);
  WATERGS_CUDA_CHECK(
      nn_kernels::CopyChannels(dconcat_.ptr(), cover.n, bits + ch + 3, bits, ch,
                               cover.PlaneSize(), dblock_.ptr(), ch, 0));
  for (int i = int(blocks_.size()) - 1; i >= 0; --i) {
    const DeviceTensor& input = i == 0 ? cover : blocks_[i - 1]->output();
    blocks_[i]->Backward(input, &dblock_, i == 0 ? nullptr : &dblock_in_, true,
                         training);
    std::swap(dblock_, dblock_in_);
  }
}

void CudaHiddenEncoder::CollectParameters(std::vector<CudaParameter*>* out) {
  for (auto& block : blocks_) block->CollectParameters(out);
  after_concat_->CollectParameters(out);
  out->push_back(&final_->weight);
  out->push_back(&final_->bias);
}

CudaHiddenModel::CudaHiddenModel(CudaNnContext* context, HiddenModel& cpu) {
  if (cpu.encoder)
    encoder =
        std::make_unique<CudaHiddenEncoder>(context, cpu.config, *cpu.encoder);
  decoder =
      std::make_unique<CudaHiddenDecoder>(context, cpu.config, *cpu.decoder);
}

std::vector<CudaParameter*> CudaHiddenModel::AllParameters() {
  std::vector<CudaParameter*> params;
  if (encoder) encoder->CollectParameters(&params);
  decoder->CollectParameters(&params);
  return params;
}

void CudaHiddenModel::CopyToHost(HiddenModel* cpu) {
  const std::vector<CudaParameter*> device = AllParameters();
  const std::vector<Parameter*> host = cpu->AllParameters();
  if (device.size() != host.size())
    Fail("CudaHiddenModel: the CPU model has another architecture");
  for (size_t i = 0; i < device.size(); ++i) {
    if (device[i]->name != host[i]->name)
      Fail("CudaHiddenModel: parameter " + host[i]->name + " where " +
           device[i]->name + " was expected");
    device[i]->CopyToHost(host[i]);
  }
}

CudaDecoder CudaDecoder::Load(const std::string& path, int expected_bits,
                              bool allow_tf32) {
  std::unique_ptr<HiddenModel> model =
      LoadHiddenModel(path, false, expected_bits);
  return CudaDecoder(*model, allow_tf32);
}

CudaDecoder::CudaDecoder(HiddenModel& model, bool allow_tf32)
    : context_(std::make_unique<CudaNnContext>(allow_tf32)),
      network_(std::make_unique<CudaHiddenDecoder>(context_.get(), model.config,
                                                   *model.decoder)) {}
CudaDecoder::CudaDecoder(CudaDecoder&& other) noexcept {
  *this = std::move(other);
}

// Member-wise, except that the cached forward pass is dropped: the network
// saved a pointer to the source's input_, which a later InputGradient would
// read (once the source is gone, with garbage shapes).
CudaDecoder& CudaDecoder::operator=(CudaDecoder&& other) noexcept {
  DevicePatchDecoder::operator=(std::move(other));
  network_ = std::move(other.network_);  // before the context it points into
  context_ = std::move(other.context_);
  input_ = std::move(other.input_);
  dlogits_ = std::move(other.dlogits_);
  dinput_ = std::move(other.dinput_);
  return *this;
}

CudaDecoder::~CudaDecoder() = default;

int CudaDecoder::NumBits() const { return network_->num_bits(); }

std::vector<float> CudaDecoder::ForwardDevice(const float* image_hwc, int width,
                                              int height, int pitch) {
  input_.Resize(1, 3, height, width);
  WATERGS_CUDA_CHECK(
      nn_kernels::ImageToInput(image_hwc, width, height, pitch, input_.ptr()));
  std::vector<float> logits;
  network_->Forward(input_, false).data.Download(&logits);
  return logits;
}

void CudaDecoder::BackwardDevice(const std::vector<float>& dlogits,
                                 float* dimage_hwc, int pitch,
                                 bool accumulate) {
  CheckLogitGradients(dlogits.size());
  dlogits_.Resize(1, NumBits(), 1, 1);
  dlogits_.data.Upload(dlogits);
  network_->Backward(dlogits_, &dinput_, false, false);
  WATERGS_CUDA_CHECK(nn_kernels::InputGradientToImage(
      dinput_.ptr(), dinput_.w, dinput_.h, pitch, accumulate, dimage_hwc));
}

ImageRGB CudaDecoder::InputGradient(const ImageRGB& image,
                                    const std::vector<float>& dlogits) {
  ImageRGB dimage;
  InputGradient(image, dlogits, &dimage);
  return dimage;
}

std::vector<float> CudaDecoder::LogitsDevice(const float* image_hwc, int width,
                                             int height) {
  return ForwardUncached(image_hwc, width, height);
}

void CudaDecoder::InputGradientDevice(const float* image_hwc, int width,
                                      int height,
                                      const std::vector<float>& dlogits,
                                      float* dimage_hwc) {
  LogitsDevice(image_hwc, width, height);
  BackwardDevice(dlogits, dimage_hwc, width, false);
}

}  // namespace watergs
