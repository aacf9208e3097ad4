// The steerable random-feature decoder (see feature_decoder.h).
#include "watermark/feature_decoder.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>
#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

// y [N,C,h,w] -> features [N,C,1,1]: ReLU then global average pooling in one
// pass, without the ReLU's output (C h w floats a call: 22 MB at 2,048
// channels on a 240x180 render). Sums as GlobalAvgPoolForward over ReLU'd
// planes do, so the features are the same to the bit.
void ReluGlobalAvgPoolForward(const Tensor& y, Tensor* features) {
  features->Resize(y.n, y.c, 1, 1);
  const size_t hw = y.PlaneSize();
  const int planes = y.n * y.c;
#pragma omp parallel for schedule(static)
  for (int k = 0; k < planes; ++k) {
    const float* p = y.Plane(k / y.c, k % y.c);
    double sum = 0.0;
    for (size_t i = 0; i < hw; ++i) sum += p[i] > 0.f ? p[i] : 0.f;
    features->data[k] = float(sum / double(hw));
  }
}

// Its backward: dy = dfeatures / hw where the convolution's output y > 0,
// 0 elsewhere (the ReLU's mask, read from y itself).
void ReluGlobalAvgPoolBackward(const Tensor& dfeatures, const Tensor& y,
                               Tensor* dy) {
  dy->ResizeLike(y);
  const size_t hw = y.PlaneSize();
  const int planes = y.n * y.c;
#pragma omp parallel for schedule(static)
  for (int k = 0; k < planes; ++k) {
    const float g = dfeatures.data[k] / float(hw);
    const float* p = y.Plane(k / y.c, k % y.c);
    float* d = dy->Plane(k / y.c, k % y.c);
    for (size_t i = 0; i < hw; ++i) d[i] = p[i] > 0.f ? g : 0.f;
  }
}

// One line of n values `stride` apart -> its clipped box mean of radius r
// (adjoint: the adjoint of that map). Prefix sums in double.
void BoxLine(const float* in, float* out, int n, size_t stride, int r,
             bool adjoint, std::vector<double>* prefix) {
  prefix->assign(size_t(n) + 1, 0.0);
  auto count = [&](int i) {
    return std::min(n - 1, i + r) - std::max(0, i - r) + 1;
  };
  for (int i = 0; i < n; ++i) {
    const double v = in[size_t(i) * stride];
    (*prefix)[i + 1] = (*prefix)[i] + (adjoint ? v / count(i) : v);
  }
  for (int i = 0; i < n; ++i) {
    const int lo = std::max(0, i - r), hi = std::min(n - 1, i + r);
    const double sum = (*prefix)[hi + 1] - (*prefix)[lo];
    out[size_t(i) * stride] = float(adjoint ? sum : sum / count(i));
  }
}

// x [N,C,H,W] -> y = x - B x (adjoint: x - B^T x), B the separable box.
void Highpass(const Tensor& x, int r, bool adjoint, Tensor* y) {
  y->ResizeLike(x);
  const int planes = x.n * x.c;
#pragma omp parallel for schedule(static)
  for (int k = 0; k < planes; ++k) {
    std::vector<double> prefix;
    std::vector<float> rows(x.PlaneSize()), box(x.PlaneSize());
    const float* in = x.Plane(k / x.c, k % x.c);
    for (int row = 0; row < x.h; ++row)
      BoxLine(in + size_t(row) * x.w, rows.data() + size_t(row) * x.w, x.w, 1,
              r, adjoint, &prefix);
    for (int col = 0; col < x.w; ++col)
      BoxLine(rows.data() + col, box.data() + col, x.h, x.w, r, adjoint,
              &prefix);
    float* out = y->Plane(k / x.c, k % x.c);
    for (size_t i = 0; i < x.PlaneSize(); ++i) out[i] = in[i] - box[i];
  }
}

constexpr int64_t kDesignVersion = 1;

FeatureDecoderConfig CheckedConfig(const FeatureDecoderConfig& config) {
  if (config.num_bits < 1 || config.num_bits > 1024)
    Fail("feature decoder: num_bits " + std::to_string(config.num_bits) +
         " outside [1, 1024]");
  if (config.channels < 1 || config.channels > 4096)
    Fail("feature decoder: channels " + std::to_string(config.channels) +
         " outside [1, 4096]");
  if (config.pool < 1 || config.pool > 64)
    Fail("feature decoder: pool " + std::to_string(config.pool) +
         " outside [1, 64]");
  if (config.kernel < 1 || config.kernel > 15 || config.kernel % 2 == 0)
    Fail("feature decoder: kernel " + std::to_string(config.kernel) +
         " is not odd in [1, 15]");
  if (config.highpass < 0 || config.highpass > 64)
    Fail("feature decoder: highpass " + std::to_string(config.highpass) +
         " outside [0, 64]");
  return config;
}

// 3 -> C convolution with PyTorch's default initialisation, from `seed`.
Conv2d RandomConv(const FeatureDecoderConfig& config, uint32_t seed) {
  std::mt19937 rng(seed);
  return Conv2d("conv", 3, config.channels, config.kernel, &rng);
}

// C -> L linear layer, all zero (calibration sets it).
Linear ZeroLinear(const FeatureDecoderConfig& config) {
  std::mt19937 rng(0);
  Linear linear("linear", config.channels, config.num_bits, &rng);
  std::fill(linear.weight.value.begin(), linear.weight.value.end(), 0.f);
  std::fill(linear.bias.value.begin(), linear.bias.value.end(), 0.f);
  return linear;
}

// dy [1,C,h,w] of a 3 -> C convolution (weights [C,3,k,k], zero padding
// k/2) -> dx [1,3,h,w]: dcol = W^T dy (3k^2 x hw), then each column entry
// added back to the input pixel it was read from. C k^2 multiply-adds a
// pixel and a 3k^2 x hw buffer, where Conv2d::Backward's im2col of dy needs
// a C k^2 x hw one (1024 channels at 60x45: 100 MB).
void ConvInputGradient(const Conv2d& conv, const Tensor& dy,
                       std::vector<float>* dcol, Tensor* dx) {
  const int k = conv.kernel(), pad = k / 2, rows = 3 * k * k;
  const int h = dy.h, w = dy.w;
  const size_t hw = size_t(h) * w;
  using ConstMap =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic,
                                     Eigen::RowMajor>>;
  using Map = Eigen::Map<
      Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  dcol->resize(size_t(rows) * hw);
  Map(dcol->data(), rows, hw).noalias() =
      ConstMap(conv.weight.value.data(), conv.out_channels(), rows)
          .transpose() *
      ConstMap(dy.Plane(0, 0), conv.out_channels(), hw);
  dx->Resize(1, 3, h, w);
  dx->Fill(0.f);
  for (int c = 0; c < 3; ++c) {
    float* plane = dx->Plane(0, c);
    for (int ky = 0; ky < k; ++ky) {
      for (int kx = 0; kx < k; ++kx) {
        const float* row = dcol->data() + (size_t(c * k + ky) * k + kx) * hw;
        for (int y = 0; y < h; ++y) {
          const int sy = y + ky - pad;
          if (sy < 0 || sy >= h) continue;
          const int x0 = std::max(0, pad - kx), x1 = std::min(w, w + pad - kx);
          float* out = plane + size_t(sy) * w + kx - pad;
          const float* in = row + size_t(y) * w;
          for (int x = x0; x < x1; ++x) out[x] += in[x];
        }
      }
    }
  }
}

}  // namespace

void HighpassForward(const Tensor& x, int r, Tensor* y) {
  Highpass(x, r, false, y);
}

void HighpassBackward(const Tensor& dy, int r, Tensor* dx) {
  Highpass(dy, r, true, dx);
}

void AvgPoolForward(const Tensor& x, int p, Tensor* y) {
  const int h = x.h / p, w = x.w / p;
  y->Resize(x.n, x.c, h, w);
  const float scale = 1.f / float(p * p);
  for (int b = 0; b < x.n; ++b) {
    for (int c = 0; c < x.c; ++c) {
      const float* in = x.Plane(b, c);
      float* out = y->Plane(b, c);
      std::fill(out, out + size_t(h) * w, 0.f);
      for (int r = 0; r < h * p; ++r) {
        const float* row = in + size_t(r) * x.w;
        float* out_row = out + size_t(r / p) * w;
        for (int col = 0; col < w * p; ++col) out_row[col / p] += row[col];
      }
      for (size_t i = 0; i < size_t(h) * w; ++i) out[i] *= scale;
    }
  }
}

void AvgPoolBackward(const Tensor& dy, int p, const Tensor& like, Tensor* dx) {
  dx->ResizeLike(like);
  dx->Fill(0.f);
  const float scale = 1.f / float(p * p);
  for (int b = 0; b < like.n; ++b) {
    for (int c = 0; c < like.c; ++c) {
      const float* g = dy.Plane(b, c);
      float* out = dx->Plane(b, c);
      for (int r = 0; r < dy.h * p; ++r) {
        const float* g_row = g + size_t(r / p) * dy.w;
        float* row = out + size_t(r) * like.w;
        for (int col = 0; col < dy.w * p; ++col)
          row[col] = g_row[col / p] * scale;
      }
    }
  }
}

FeatureNet::FeatureNet(const FeatureDecoderConfig& config, uint32_t seed)
    : conv(RandomConv(CheckedConfig(config), seed)),
      linear(ZeroLinear(config)),
      config_(config) {}

double FeatureNet::MacsPerPixel() const {
  const double conv_macs =
      double(conv.MacsPerPixel()) / double(config_.pool * config_.pool);
  return 1.0 + conv_macs;  // pooling: one add per input value and pixel
}

void FeatureNet::ConvolutionOutput(const Tensor& image, Tensor* y) {
  PrepareConvInput(image);
  conv.Forward(ConvInput(), y);
  image_ = nullptr;
}

const Tensor& FeatureNet::Forward(const Tensor& image) {
  PrepareConvInput(image);
  last_n_ = image.n;
  if (image.n == 1) {
    // A batch's conv output may be large: free it.
    conv_out_ = Tensor();
    StripForward(ConvInput());
  } else {
    conv.Forward(ConvInput(), &conv_out_);
    ReluGlobalAvgPoolForward(conv_out_, &features_);
  }
  linear.Forward(features_, &logits_);
  return logits_;
}

void FeatureNet::PrepareConvInput(const Tensor& image) {
  if (image.c != 3 || image.h < config_.pool || image.w < config_.pool)
    Fail("feature decoder: input of " + std::to_string(image.w) + "x" +
         std::to_string(image.h) + " pixels (" + std::to_string(image.c) +
         " channels) is smaller than its " + std::to_string(config_.pool) +
         "x" + std::to_string(config_.pool) + " pooling");
  image_ = &image;
  if (config_.pool > 1) AvgPoolForward(image, config_.pool, &pooled_);
  if (config_.highpass > 0)
    HighpassForward(config_.pool > 1 ? pooled_ : image, config_.highpass,
                    &residual_);
}

int FeatureNet::StripRows(int h, int w) const {
  const size_t row_bytes = size_t(conv.out_channels()) * w * sizeof(float);
  const int pad = conv.kernel() / 2;
  const size_t fit = max_strip_bytes_ / std::max<size_t>(row_bytes, 1);
  // A strip computes its halo rows again; whole images where they fit.
  if (fit >= size_t(h)) return h;
  return std::max(1, int(fit) - 2 * pad);
}

namespace {

// Rows [a, b) of a [1,C,h,w] tensor -> out [1,C,b-a,w].
void CopyRows(const Tensor& x, int a, int b, Tensor* out) {
  out->Resize(1, x.c, b - a, x.w);
  for (int c = 0; c < x.c; ++c) {
    std::copy(x.Plane(0, c) + size_t(a) * x.w, x.Plane(0, c) + size_t(b) * x.w,
              out->Plane(0, c));
  }
}

}  // namespace

// Strip [r0, r1) of the output rows is computed from input rows [a, b), its
// rows widened by the kernel's reach and clipped to the image: each output
// row in [r0, r1) then sees exactly the rows (or the zero padding) it sees
// in the whole image.
void FeatureNet::StripForward(const Tensor& input) {
  const int h = input.h, w = input.w, channels = conv.out_channels();
  const int pad = conv.kernel() / 2, rows = StripRows(h, w);
  const size_t hw = size_t(h) * w;
  mask_words_per_channel_ = (hw + 63) / 64;
  relu_mask_.assign(size_t(channels) * mask_words_per_channel_, 0);
  std::vector<double> sums(channels, 0.0);
  for (int r0 = 0; r0 < h; r0 += rows) {
    const int r1 = std::min(h, r0 + rows);
    const int a = std::max(0, r0 - pad), b = std::min(h, r1 + pad);
    const bool whole = a == 0 && b == h;
    if (!whole) CopyRows(input, a, b, &strip_in_);
    conv.Forward(whole ? input : strip_in_, &strip_out_);
    const size_t first = size_t(r0) * w, count = size_t(r1 - r0) * w;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < channels; ++c) {
      const float* p = strip_out_.Plane(0, c) + size_t(r0 - a) * w;
      uint64_t* bits = relu_mask_.data() + size_t(c) * mask_words_per_channel_;
      double sum = 0.0;
      for (size_t i = 0; i < count; ++i) {
        if (!(p[i] > 0.f)) continue;
        sum += p[i];
        const size_t at = first + i;
        bits[at >> 6] |= uint64_t(1) << (at & 63);
      }
      sums[c] += sum;
    }
  }
  features_.Resize(1, channels, 1, 1);
  for (int c = 0; c < channels; ++c)
    features_.data[c] = float(sums[c] / double(hw));
  last_num_strips_ = (h + rows - 1) / rows;
}

// The ReLU-and-pool gradient of a strip's output rows (dfeatures / hw where
// the mask is set), zero on its halo rows, taken back through the
// convolution as if the strip were the image: the halo rows then receive
// exactly the strip's contributions, and the strips' sum is the whole
// image's input gradient.
void FeatureNet::StripBackward(const Tensor& dfeatures, Tensor* dconv_input) {
  const Tensor& input = ConvInput();
  const int h = input.h, w = input.w, channels = conv.out_channels();
  const int pad = conv.kernel() / 2, rows = StripRows(h, w);
  const size_t hw = size_t(h) * w;
  dconv_input->Resize(1, input.c, h, w);
  dconv_input->Fill(0.f);
  for (int r0 = 0; r0 < h; r0 += rows) {
    const int r1 = std::min(h, r0 + rows);
    const int a = std::max(0, r0 - pad), b = std::min(h, r1 + pad);
    strip_out_.Resize(1, channels, b - a, w);
    const size_t first = size_t(r0) * w, count = size_t(r1 - r0) * w;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < channels; ++c) {
      const float g = dfeatures.data[c] / float(hw);
      const uint64_t* bits =
          relu_mask_.data() + size_t(c) * mask_words_per_channel_;
      float* d = strip_out_.Plane(0, c);
      std::fill(d, d + size_t(r0 - a) * w, 0.f);
      float* out = d + size_t(r0 - a) * w;
      for (size_t i = 0; i < count; ++i) {
        const size_t at = first + i;
        out[i] = (bits[at >> 6] >> (at & 63)) & 1 ? g : 0.f;
      }
      std::fill(out + count, d + strip_out_.PlaneSize(), 0.f);
    }
    ConvInputGradient(conv, strip_out_, &dcol_, &strip_in_);
    for (int c = 0; c < input.c; ++c) {
      const float* from = strip_in_.Plane(0, c);
      float* to = dconv_input->Plane(0, c) + size_t(a) * w;
      for (size_t i = 0; i < strip_in_.PlaneSize(); ++i) to[i] += from[i];
    }
  }
}

const Tensor& FeatureNet::ConvInput() const {
  if (config_.highpass > 0) return residual_;
  return config_.pool > 1 ? pooled_ : *image_;
}

void FeatureNet::InputBackward(Tensor* dconv_input, Tensor* dimage) {
  Tensor* dbefore_highpass = config_.pool > 1 ? &dpooled_ : dimage;
  if (config_.highpass > 0) {
    HighpassBackward(*dconv_input, config_.highpass, dbefore_highpass);
  } else {
    std::swap(*dconv_input, *dbefore_highpass);
  }
  if (config_.pool > 1)
    AvgPoolBackward(dpooled_, config_.pool, *image_, dimage);
}

void FeatureNet::FeatureBackward(const Tensor& dfeatures, Tensor* dimage) {
  if (!image_ || last_n_ != 1) {
    Fail("feature decoder: FeatureBackward needs a single-image Forward");
  }
  StripBackward(dfeatures, &dresidual_);
  InputBackward(&dresidual_, dimage);
}

void FeatureNet::Backward(const Tensor& dlogits, Tensor* dimage) {
  if (!image_) Fail("feature decoder: Backward before Forward");
  linear.Backward(features_, dlogits, &dfeatures_, false);
  if (last_n_ == 1) {
    StripBackward(dfeatures_, &dresidual_);
  } else {
    // Batches (calibration never backpropagates): the general layer.
    ReluGlobalAvgPoolBackward(dfeatures_, conv_out_, &drelu_);
    conv.Backward(ConvInput(), drelu_, &dresidual_, false);
  }
  InputBackward(&dresidual_, dimage);
}

NetworkFile FeatureNetToFile(FeatureNet& net) {
  NetworkFile file;
  file.kind = kFeatureDecoderKind;
  const FeatureDecoderConfig& config = net.config();
  file.meta = {{"num_bits", config.num_bits},
               {"channels", config.channels},
               {"pool", config.pool},
               {"kernel", config.kernel},
               {"input_range", 1},
               {"design", kDesignVersion}};
  // Written only when set, so that a decoder without it stays the same file.
  if (config.highpass > 0) file.meta.push_back({"highpass", config.highpass});
  for (const Parameter* p :
       {&net.conv.weight, &net.conv.bias, &net.linear.weight, &net.linear.bias})
    file.tensors.push_back(TensorRecord{p->name, p->shape, p->value});
  return file;
}

std::unique_ptr<FeatureNet> FeatureNetFromFile(const std::string& path,
                                               const NetworkFile& file,
                                               int expected_bits) {
  if (file.kind != kFeatureDecoderKind)
    FailAt(path, "holds a '" + file.kind + "', not a feature decoder");
  if (file.Meta("design", path) != kDesignVersion)
    FailAt(path, "feature decoder design " +
                     std::to_string(file.Meta("design", path)) +
                     " is not supported (this build reads design " +
                     std::to_string(kDesignVersion) + ")");
  if (file.Meta("input_range", path) != 1)
    FailAt(path, "unsupported input_range " +
                     std::to_string(file.Meta("input_range", path)));
  FeatureDecoderConfig config;
  config.num_bits = int(file.Meta("num_bits", path));
  config.channels = int(file.Meta("channels", path));
  config.pool = int(file.Meta("pool", path));
  config.kernel = int(file.Meta("kernel", path));
  for (const auto& [key, value] : file.meta)
    if (key == "highpass") config.highpass = int(value);
  if (expected_bits > 0 && config.num_bits != expected_bits)
    FailAt(path, "decoder reads " + std::to_string(config.num_bits) +
                     " bits, expected " + std::to_string(expected_bits));
  std::unique_ptr<FeatureNet> net;
  try {
    net = std::make_unique<FeatureNet>(config, 0);
  } catch (const Error& e) {
    FailAt(path, e.what());
  }
  std::vector<Parameter*> params = {&net->conv.weight, &net->conv.bias,
                                    &net->linear.weight, &net->linear.bias};
  if (file.tensors.size() != params.size())
    FailAt(path, "holds " + std::to_string(file.tensors.size()) +
                     " tensors, a feature decoder has " +
                     std::to_string(params.size()));
  for (Parameter* p : params) {
    const TensorRecord* record = file.Find(p->name);
    if (!record) FailAt(path, "missing tensor " + p->name);
    if (record->shape != p->shape)
      FailAt(path, "tensor " + p->name + " has the wrong shape");
    for (float v : record->values)
      if (!std::isfinite(v))
        FailAt(path, "tensor " + p->name + " holds NaN or Inf");
    p->value = record->values;
  }
  return net;
}

std::unique_ptr<FeatureDecoder> FeatureDecoder::Load(const std::string& path,
                                                     int expected_bits) {
  return std::make_unique<FeatureDecoder>(
      FeatureNetFromFile(path, ReadNetworkFile(path), expected_bits));
}

FeatureDecoder::FeatureDecoder(std::unique_ptr<FeatureNet> net)
    : net_(std::move(net)) {}

int FeatureDecoder::NumBits() const { return net_->config().num_bits; }

const Tensor& FeatureDecoder::ForwardTensor(const Tensor& input) {
  return net_->Forward(input);
}

void FeatureDecoder::BackwardTensor(const Tensor& dlogits, Tensor* dinput) {
  net_->Backward(dlogits, dinput);
}

}  // namespace watergs
