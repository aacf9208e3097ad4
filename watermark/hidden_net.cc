// HiDDeN encoder and decoder (see hidden_net.h).
#include "watermark/hidden_net.h"

#include <string>

namespace watergs {

ConvBnRelu::ConvBnRelu(const std::string& name, int in, int out,
                       std::mt19937* rng)
    : conv(name + ".conv", in, out, 3, rng), bn(name + ".bn", out) {}

void ConvBnRelu::Forward(const Tensor& x, bool training) {
  conv.Forward(x, &conv_out_);
  bn.Forward(conv_out_, &out_, training);
  ReluForward(&out_);
}

void ConvBnRelu::Backward(const Tensor& x, Tensor* dout, Tensor* dx,
                          bool weight_grads, bool training) {
  ReluBackward(out_, dout);
  bn.Backward(conv_out_, *dout, &dconv_, weight_grads, training);
  conv.Backward(x, dconv_, dx, weight_grads);
}

void ConvBnRelu::CollectParameters(std::vector<Parameter*>* out) {
  for (Parameter* p : {&conv.weight, &conv.bias, &bn.gamma, &bn.beta,
                       &bn.running_mean, &bn.running_var})
    out->push_back(p);
}

HiddenEncoder::HiddenEncoder(const HiddenConfig& config, std::mt19937* rng)
    : config_(config),
      after_concat_("encoder.after_concat",
                    config.num_bits + config.channels + 3, config.channels,
                    rng),
      final_("encoder.final", config.channels, 3, 1, rng) {
  for (int i = 0; i < config.encoder_blocks; ++i)
    blocks_.emplace_back("encoder.block" + std::to_string(i),
                         i == 0 ? 3 : config.channels, config.channels, rng);
  // A small initial residual (~36 dB) so training starts imperceptible and
  // the message loss, not the image loss, dominates the first steps.
  for (float& w : final_.weight.value) w *= 0.1f;
  std::fill(final_.bias.value.begin(), final_.bias.value.end(), 0.f);
}

const Tensor& HiddenEncoder::Forward(const Tensor& cover,
                                     const std::vector<float>& message,
                                     bool training) {
  cover_ = &cover;
  const Tensor* x = &cover;
  for (ConvBnRelu& block : blocks_) {
    block.Forward(*x, training);
    x = &block.output();
  }
  const int bits = config_.num_bits, ch = config_.channels;
  concat_.Resize(cover.n, bits + ch + 3, cover.h, cover.w);
  const size_t hw = cover.PlaneSize();
  for (int b = 0; b < cover.n; ++b) {
    for (int i = 0; i < bits; ++i)
      std::fill(concat_.Plane(b, i), concat_.Plane(b, i) + hw,
                message[size_t(b) * bits + i]);
    std::copy(x->Plane(b, 0), x->Plane(b, 0) + ch * hw, concat_.Plane(b, bits));
    std::copy(cover.Plane(b, 0), cover.Plane(b, 0) + 3 * hw,
              concat_.Plane(b, bits + ch));
  }
  after_concat_.Forward(concat_, training);
  final_.Forward(after_concat_.output(), &residual_);
  watermarked_.ResizeLike(cover);
  for (size_t i = 0; i < cover.size(); ++i)
    watermarked_.data[i] = cover.data[i] + residual_.data[i];
  return watermarked_;
}

void HiddenEncoder::Backward(const Tensor& dwatermarked, bool training) {
  // d residual = d watermarked.
  final_.Backward(after_concat_.output(), dwatermarked, &dblock_, true);
  after_concat_.Backward(concat_, &dblock_, &dconcat_, true, training);
  const int bits = config_.num_bits, ch = config_.channels;
  const size_t hw = cover_->PlaneSize();
  dblock_.Resize(cover_->n, ch, cover_->h, cover_->w);
  for (int b = 0; b < cover_->n; ++b)
    std::copy(dconcat_.Plane(b, bits), dconcat_.Plane(b, bits) + ch * hw,
              dblock_.Plane(b, 0));
  for (int i = int(blocks_.size()) - 1; i >= 0; --i) {
    const Tensor& input = i == 0 ? *cover_ : blocks_[i - 1].output();
    blocks_[i].Backward(input, &dblock_, i == 0 ? nullptr : &dblock_in_, true,
                        training);
    std::swap(dblock_, dblock_in_);
  }
}

void HiddenEncoder::CollectParameters(std::vector<Parameter*>* out) {
  for (ConvBnRelu& block : blocks_) block.CollectParameters(out);
  after_concat_.CollectParameters(out);
  out->push_back(&final_.weight);
  out->push_back(&final_.bias);
}

int64_t HiddenEncoder::MacsPerPixel() const {
  int64_t macs = after_concat_.conv.MacsPerPixel() + final_.MacsPerPixel();
  for (const ConvBnRelu& block : blocks_) macs += block.conv.MacsPerPixel();
  return macs;
}

HiddenDecoder::HiddenDecoder(const HiddenConfig& config, std::mt19937* rng)
    : config_(config),
      linear_("decoder.linear", config.num_bits, config.num_bits, rng) {
  for (int i = 0; i < config.decoder_blocks; ++i)
    blocks_.emplace_back("decoder.block" + std::to_string(i),
                         i == 0 ? 3 : config.channels, config.channels, rng);
  blocks_.emplace_back("decoder.block" + std::to_string(config.decoder_blocks),
                       config.channels, config.num_bits, rng);
}

const Tensor& HiddenDecoder::Forward(const Tensor& image, bool training) {
  image_ = &image;
  const Tensor* x = &image;
  for (ConvBnRelu& block : blocks_) {
    block.Forward(*x, training);
    x = &block.output();
  }
  GlobalAvgPoolForward(*x, &pooled_);
  linear_.Forward(pooled_, &logits_);
  return logits_;
}

void HiddenDecoder::Backward(const Tensor& dlogits, Tensor* dimage,
                             bool weight_grads, bool training) {
  linear_.Backward(pooled_, dlogits, &dpooled_, weight_grads);
  GlobalAvgPoolBackward(dpooled_, blocks_.back().output(), &da_);
  for (int i = int(blocks_.size()) - 1; i >= 0; --i) {
    const Tensor& input = i == 0 ? *image_ : blocks_[i - 1].output();
    Tensor* dx = i == 0 ? dimage : &db_;
    if (i == 0 && !dimage && !weight_grads) break;
    blocks_[i].Backward(input, &da_, dx, weight_grads, training);
    std::swap(da_, db_);
  }
}

void HiddenDecoder::CollectParameters(std::vector<Parameter*>* out) {
  for (ConvBnRelu& block : blocks_) block.CollectParameters(out);
  out->push_back(&linear_.weight);
  out->push_back(&linear_.bias);
}

int64_t HiddenDecoder::MacsPerPixel() const {
  int64_t macs = 0;
  for (const ConvBnRelu& block : blocks_) macs += block.conv.MacsPerPixel();
  return macs;
}

}  // namespace watergs
