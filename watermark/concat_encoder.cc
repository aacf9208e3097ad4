// The "CONCAT + 3DGS" baseline (see concat_encoder.h).
#include "watermark/concat_encoder.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/progress.h"
#include "watermark/embedder.h"

namespace watergs {
namespace {

template <typename T>
using RowMatrix =
    Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <typename T>
using ConstMap = Eigen::Map<const RowMatrix<T>>;
template <typename T>
using MutableMap = Eigen::Map<RowMatrix<T>>;
template <typename T>
using ConstVector = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>>;
template <typename T>
using MutableVector = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>>;

// Coefficients of `target` at `sh_degree`; Error if there are none or the
// message length or hidden width is not positive.
int CheckedCoeffs(const ShTarget& target, int sh_degree, int num_bits,
                  int hidden) {
  if (num_bits < 1) Fail("concat encoder: the message needs at least 1 bit");
  if (hidden < 1) Fail("concat encoder: --hidden must be at least 1");
  if (target.rest && !target.dc && sh_degree == 0) {
    Fail("concat encoder: f_rest is empty in an SH degree 0 model");
  }
  const int coeffs = target.NumCoeffs(sh_degree);
  if (coeffs == 0) Fail("concat encoder: no SH group chosen");
  return coeffs;
}

Linear MakeLinear(const std::string& name, int in, int out, uint32_t seed) {
  std::mt19937 rng(seed);
  return Linear(name, in, out, &rng);
}

}  // namespace

int ShTarget::NumCoeffs(int sh_degree) const {
  return (dc ? 3 : 0) + (rest ? 3 * (NumShCoeffs(sh_degree) - 1) : 0);
}

ShTarget ParseShTarget(const std::string& text) {
  ShTarget target{false, false};
  std::istringstream in(text);
  std::string name;
  while (std::getline(in, name, ',')) {
    if (name == "f_dc" || name == "sh") target.dc = true;
    if (name == "f_rest" || name == "sh") target.rest = true;
    if (name != "f_dc" && name != "f_rest" && name != "sh") {
      Fail("--attributes: unknown SH group '" + name +
           "' (use f_dc, f_rest or sh for both)");
    }
  }
  if (!target.dc && !target.rest) Fail("--attributes: no SH group given");
  return target;
}

void PackShRow(const GaussianModel& model, const ShTarget& target, size_t i,
               float* row) {
  const int stride = model.sh_rest_stride();
  if (target.dc) row = std::copy_n(&model.sh_dc[3 * i], 3, row);
  if (target.rest) std::copy_n(&model.sh_rest[stride * i], stride, row);
}

void AddShRow(const ShTarget& target, const float* offset, size_t i,
              GaussianModel* model) {
  if (target.dc) {
    for (int k = 0; k < 3; ++k) model->sh_dc[3 * i + k] += *offset++;
  }
  const int stride = model->sh_rest_stride();
  if (target.rest) {
    for (int k = 0; k < stride; ++k)
      model->sh_rest[stride * i + k] += offset[k];
  }
}

template <typename T>
void ConcatMlpForward(const ConcatMlpWeights<const T>& w,
                      std::span<const T> inputs, std::span<const T> signs,
                      std::vector<T>* offsets, std::vector<T>* hidden) {
  const Eigen::Index n = inputs.size() / w.coeffs;
  const ConstMap<T> x(inputs.data(), n, w.coeffs);
  const ConstMap<T> w1(w.w1.data(), w.hidden, w.coeffs + w.bits);
  const ConstMap<T> w2(w.w2.data(), w.coeffs, w.hidden);
  const Eigen::Matrix<T, Eigen::Dynamic, 1> bias =
      ConstVector<T>(w.b1.data(), w.hidden) +
      w1.rightCols(w.bits) * ConstVector<T>(signs.data(), w.bits);
  hidden->resize(size_t(n) * w.hidden);
  MutableMap<T> h(hidden->data(), n, w.hidden);
  h.noalias() = x * w1.leftCols(w.coeffs).transpose();
  h.rowwise() += bias.transpose();
  h = h.cwiseMax(T(0));
  offsets->resize(inputs.size());
  MutableMap<T> out(offsets->data(), n, w.coeffs);
  out.noalias() = h * w2.transpose();
  out.rowwise() += ConstVector<T>(w.b2.data(), w.coeffs).transpose();
}

template <typename T>
void ConcatMlpBackward(const ConcatMlpWeights<const T>& w,
                       std::span<const T> inputs, std::span<const T> signs,
                       std::span<const T> hidden, std::span<const T> doffsets,
                       const ConcatMlpWeights<T>& grads) {
  const Eigen::Index n = inputs.size() / w.coeffs;
  const ConstMap<T> x(inputs.data(), n, w.coeffs);
  const ConstMap<T> h(hidden.data(), n, w.hidden);
  const ConstMap<T> dout(doffsets.data(), n, w.coeffs);
  const ConstMap<T> w2(w.w2.data(), w.coeffs, w.hidden);
  MutableMap<T>(grads.w2.data(), w.coeffs, w.hidden).noalias() +=
      dout.transpose() * h;
  // Column sums go into an owned (aligned) vector first: evaluated straight
  // into the unaligned grad buffer, Eigen would sum some columns in packets
  // and the rest one by one depending on that buffer's address, so the
  // result would change in the last bit from one process to the next.
  const Eigen::Matrix<T, Eigen::Dynamic, 1> db2 = dout.colwise().sum();
  MutableVector<T>(grads.b2.data(), w.coeffs) += db2;
  // Through the ReLU: zero where the unit was off.
  RowMatrix<T> dh = dout * w2;
  dh = (h.array() > T(0)).select(dh, T(0));
  MutableMap<T> dw1(grads.w1.data(), w.hidden, w.coeffs + w.bits);
  dw1.leftCols(w.coeffs).noalias() += dh.transpose() * x;
  const Eigen::Matrix<T, Eigen::Dynamic, 1> dbias = dh.colwise().sum();
  dw1.rightCols(w.bits).noalias() +=
      dbias * ConstVector<T>(signs.data(), w.bits).transpose();
  MutableVector<T>(grads.b1.data(), w.hidden) += dbias;
}

template void ConcatMlpForward<float>(const ConcatMlpWeights<const float>&,
                                      std::span<const float>,
                                      std::span<const float>,
                                      std::vector<float>*, std::vector<float>*);
template void ConcatMlpForward<double>(const ConcatMlpWeights<const double>&,
                                       std::span<const double>,
                                       std::span<const double>,
                                       std::vector<double>*,
                                       std::vector<double>*);
template void ConcatMlpBackward<float>(const ConcatMlpWeights<const float>&,
                                       std::span<const float>,
                                       std::span<const float>,
                                       std::span<const float>,
                                       std::span<const float>,
                                       const ConcatMlpWeights<float>&);
template void ConcatMlpBackward<double>(const ConcatMlpWeights<const double>&,
                                        std::span<const double>,
                                        std::span<const double>,
                                        std::span<const double>,
                                        std::span<const double>,
                                        const ConcatMlpWeights<double>&);

ConcatEncoder::ConcatEncoder(const ShTarget& target, int sh_degree,
                             int num_bits, int hidden, uint32_t seed)
    : target_(target),
      sh_degree_(sh_degree),
      num_bits_(num_bits),
      coeffs_(CheckedCoeffs(target, sh_degree, num_bits, hidden)),
      hidden_(hidden),
      fc1_(MakeLinear("concat.fc1", coeffs_ + num_bits, hidden, seed)),
      fc2_(MakeLinear("concat.fc2", hidden, coeffs_, seed + 1)) {
  std::fill(fc2_.weight.value.begin(), fc2_.weight.value.end(), 0.f);
  std::fill(fc2_.bias.value.begin(), fc2_.bias.value.end(), 0.f);
}

std::vector<Parameter*> ConcatEncoder::Parameters() {
  return {&fc1_.weight, &fc1_.bias, &fc2_.weight, &fc2_.bias};
}

ConcatMlpWeights<const float> ConcatEncoder::Weights() const {
  return {coeffs_,         num_bits_,         hidden_,        fc1_.weight.value,
          fc1_.bias.value, fc2_.weight.value, fc2_.bias.value};
}

void ConcatEncoder::CheckFits(const GaussianModel& model,
                              const Bits& message) const {
  if (model.sh_degree != sh_degree_) {
    Fail("concat encoder: built for SH degree " + std::to_string(sh_degree_) +
         ", the model has degree " + std::to_string(model.sh_degree));
  }
  if (static_cast<int>(message.size()) != num_bits_) {
    Fail("concat encoder: built for " + std::to_string(num_bits_) +
         "-bit messages, got " + std::to_string(message.size()) + " bits");
  }
}

void ConcatEncoder::Apply(const GaussianModel& model, const Bits& message,
                          GaussianModel* out) const {
  CheckFits(model, message);
  if (const size_t bad = model.CountNonFinite()) {
    Fail("concat encoder: the model holds " + std::to_string(bad) +
         " NaN/Inf values");
  }
  const std::vector<float> signs = BitSigns(message);
  *out = model;
  // In blocks of Gaussians, so that the hidden layer of a large scene is
  // never held at once.
  constexpr size_t kBlock = 1 << 16;
  std::vector<float> inputs, offsets, hidden;
  for (size_t begin = 0; begin < model.size(); begin += kBlock) {
    const size_t end = std::min(model.size(), begin + kBlock);
    inputs.resize((end - begin) * coeffs_);
    for (size_t i = begin; i < end; ++i) {
      PackShRow(model, target_, i, &inputs[(i - begin) * coeffs_]);
    }
    ConcatMlpForward<float>(Weights(), inputs, signs, &offsets, &hidden);
    for (size_t i = begin; i < end; ++i) {
      AddShRow(target_, &offsets[(i - begin) * coeffs_], i, out);
    }
  }
  if (out->CountNonFinite() != 0) {
    Fail("concat encoder: the offsets overflow (non-finite SH coefficients)");
  }
}

GaussianModel ConcatEncoder::Apply(const GaussianModel& model,
                                   const Bits& message) const {
  GaussianModel out;
  Apply(model, message, &out);
  return out;
}

void ConcatEncoder::Backward(const GaussianModel& model, const Bits& message,
                             const GaussianGradients& grads) {
  // Sizes only: the model is the one Apply checked for NaN/Inf.
  CheckFits(model, message);
  const size_t n = model.size();
  const size_t stride = model.sh_rest_stride();
  if (grads.sh_dc.size() != 3 * n || grads.sh_rest.size() != stride * n ||
      (!grads.visible.empty() && grads.visible.size() != n)) {
    Fail("concat encoder: the gradients do not match the model");
  }
  // Only Gaussians with a gradient contribute: gather those rows (a crop
  // sees few of a scene's Gaussians).
  rows_inputs_.clear();
  rows_doffsets_.clear();
  for (size_t i = 0; i < n; ++i) {
    if (!grads.visible.empty() && !grads.visible[i]) continue;
    rows_inputs_.resize(rows_inputs_.size() + coeffs_);
    PackShRow(model, target_, i, &rows_inputs_[rows_inputs_.size() - coeffs_]);
    const float* dc = &grads.sh_dc[3 * i];
    const float* rest = grads.sh_rest.data() + stride * i;
    if (target_.dc) rows_doffsets_.insert(rows_doffsets_.end(), dc, dc + 3);
    if (target_.rest) {
      rows_doffsets_.insert(rows_doffsets_.end(), rest, rest + stride);
    }
  }
  const std::vector<float> signs = BitSigns(message);
  ConcatMlpForward<float>(Weights(), rows_inputs_, signs, &rows_offsets_,
                          &rows_hidden_);
  const ConcatMlpWeights<float> g{
      coeffs_,        num_bits_,        hidden_,       fc1_.weight.grad,
      fc1_.bias.grad, fc2_.weight.grad, fc2_.bias.grad};
  ConcatMlpBackward<float>(Weights(), rows_inputs_, signs, rows_hidden_,
                           rows_doffsets_, g);
}

ConcatEncoderTrainer::ConcatEncoderTrainer(
    const ConcatTrainOptions& options, const TrainingViews& views,
    std::vector<size_t> train_views, const GaussianModel& model,
    BitDecoder* decoder, Rasterizer* rasterizer, ConcatEncoder* encoder)
    : options_(options),
      views_(views),
      train_views_(std::move(train_views)),
      model_(model),
      decoder_(decoder),
      rasterizer_(rasterizer),
      encoder_(encoder),
      adam_(encoder->Parameters(), float(options.learning_rate)),
      loss_(options.beta),
      rng_(options.seed) {
  if (train_views_.empty()) Fail("concat_embed: no training views");
  for (size_t v : train_views_) {
    if (v >= views_.NumViews()) Fail("concat_embed: view index out of range");
  }
  if (decoder_->NumBits() != encoder_->num_bits()) {
    Fail("concat_embed: the encoder writes " +
         std::to_string(encoder_->num_bits()) + " bits, the decoder reads " +
         std::to_string(decoder_->NumBits()));
  }
  if (model_.size() == 0) Fail("concat_embed: the model has no Gaussians");
  if (const size_t bad = model_.CountNonFinite()) {
    Fail("concat_embed: the model holds " + std::to_string(bad) +
         " NaN/Inf values");
  }
  if (!(options_.learning_rate > 0 && std::isfinite(options_.learning_rate))) {
    Fail("concat_embed: the learning rate must be positive");
  }
}

ConcatStepStats ConcatEncoderTrainer::Step() {
  ConcatStepStats stats;
  stats.iteration = iteration_ + 1;
  Bits message(encoder_->num_bits());
  for (auto& bit : message) bit = rng_() & 1;
  encoder_->Apply(model_, message, &encoded_);

  const size_t view = train_views_[rng_() % train_views_.size()];
  const RenderCamera camera = views_.Camera(view);
  const std::shared_ptr<const ImageRGB> truth = views_.Image(view);
  RenderOptions render_options;
  render_options.background = options_.background;
  if (options_.crop_size > 0) {
    render_options.rect =
        RandomCrop(options_.crop_size, camera.width, camera.height, &rng_);
    CropImage(*truth, render_options.rect, &truth_crop_);
  }
  std::unique_ptr<RenderContext> context;
  rasterizer_->Forward(encoded_, camera, render_options, &render_, &context);
  stats.image = loss_.Evaluate(
      render_, options_.crop_size > 0 ? truth_crop_ : *truth, &grad_image_);
  // The decoder reads the whole render (the crop when cropping).
  const std::vector<float> targets(message.begin(), message.end());
  stats.bce = AddMessageLoss(*decoder_, render_, PixelRect{}, targets,
                             options_.gamma, &grad_image_, &stats.bit_errors);
  stats.total = stats.image.total + options_.gamma * stats.bce;
  if (!std::isfinite(stats.total)) {
    Fail("concat_embed stopped at iteration " +
         std::to_string(stats.iteration) + ": the loss is not finite on view " +
         views_.Name(view));
  }
  rasterizer_->Backward(encoded_, *context, grad_image_, &grads_);
  adam_.ZeroGrad();
  encoder_->Backward(model_, message, grads_);
  adam_.Step();
  iteration_ = stats.iteration;
  return stats;
}

ConcatStepStats TrainConcatEncoder(const ConcatTrainOptions& options,
                                   const TrainingViews& views,
                                   const std::vector<size_t>& train_views,
                                   const GaussianModel& model,
                                   BitDecoder* decoder, Rasterizer* rasterizer,
                                   ConcatEncoder* encoder) {
  ConcatEncoderTrainer trainer(options, views, train_views, model, decoder,
                               rasterizer, encoder);
  std::unique_ptr<ProgressBar> bar;
  if (options.show_progress) {
    bar = std::make_unique<ProgressBar>("concat_embed", options.iterations);
  }
  ConcatStepStats stats;
  RunningAverage loss(0.9), bce(0.95), ber(0.95);
  while (trainer.iteration() < options.iterations) {
    stats = trainer.Step();
    loss.Add(stats.total);
    bce.Add(stats.bce);
    ber.Add(double(stats.bit_errors) / encoder->num_bits());
    if (bar) {
      char status[128];
      std::snprintf(status, sizeof(status),
                    "loss %.4f  L1 %.4f  BCE %.3f  BER %.1f%%", loss.value(),
                    stats.image.l1, bce.value(), 100 * ber.value());
      bar->Update(stats.iteration, status);
    }
  }
  if (bar) bar->Finish("done");
  return stats;
}

}  // namespace watergs
