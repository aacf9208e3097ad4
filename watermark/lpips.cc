// LPIPS-VGG on the project's NN layers (see lpips.h).
#include "watermark/lpips.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr int kConvWidths[13] = {64,  64,  128, 128, 256, 256, 256,
                                 512, 512, 512, 512, 512, 512};
constexpr int kConvIndices[13] = {0,  2,  5,  7,  10, 12, 14,
                                  17, 19, 21, 24, 26, 28};
// Convolutions per block; a tap after each block, a pool before blocks 1-4.
constexpr int kBlockConvs[5] = {2, 2, 3, 3, 3};
constexpr int kTapChannels[5] = {64, 128, 256, 512, 512};

// CRC-32 (zlib's, the checksum the converter script writes) of `size` bytes.
uint32_t Crc32(const uint8_t* data, size_t size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib takes uInt lengths: feed the weights (~60 MB) in chunks.
  constexpr size_t kChunk = size_t(1) << 30;
  for (size_t done = 0; done < size; done += kChunk) {
    crc = crc32(crc, data + done, uInt(std::min(kChunk, size - done)));
  }
  return uint32_t(crc);
}

// Sequential little-endian reads that fail with the file's name.
class Reader {
 public:
  Reader(const std::string& path, const std::vector<uint8_t>& bytes, size_t end)
      : path_(path), bytes_(bytes), end_(end) {}
  void Read(void* out, size_t size) {
    if (size > end_ - pos_) FailAt(path_, "truncated LPIPS weights file");
    // An empty tensor's buffer may be null, which memcpy must not get.
    if (size == 0) return;
    std::memcpy(out, bytes_.data() + pos_, size);
    pos_ += size;
  }
  template <typename T>
  T Get() {
    T value;
    Read(&value, sizeof(T));
    return value;
  }
  bool AtEnd() const { return pos_ == end_; }
  size_t Remaining() const { return end_ - pos_; }

 private:
  const std::string& path_;
  const std::vector<uint8_t>& bytes_;
  size_t end_, pos_ = 0;
};

struct NamedTensor {
  std::vector<int64_t> shape;
  std::vector<float> values;
};

std::map<std::string, NamedTensor> ReadTensors(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  if (bytes.size() < 16 || std::memcmp(bytes.data(), "WGLPIPS1", 8) != 0) {
    FailAt(path, "not a watergs LPIPS-VGG weights file (magic WGLPIPS1)");
  }
  uint32_t stored_crc;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - 4, 4);
  if (Crc32(bytes.data(), bytes.size() - 4) != stored_crc) {
    FailAt(path, "CRC mismatch (corrupted or truncated LPIPS weights)");
  }
  Reader reader(path, bytes, bytes.size() - 4);
  char magic[8];
  reader.Read(magic, 8);
  const uint32_t count = reader.Get<uint32_t>();
  std::map<std::string, NamedTensor> tensors;
  for (uint32_t t = 0; t < count; ++t) {
    const uint32_t name_size = reader.Get<uint32_t>();
    if (name_size > 256) FailAt(path, "tensor name too long");
    std::string name(name_size, '\0');
    reader.Read(name.data(), name_size);
    // Names reach error messages, which must stay one line.
    for (const char c : name) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
        FailAt(path, "tensor name with a control character");
      }
    }
    const uint32_t ndim = reader.Get<uint32_t>();
    if (ndim > 4) FailAt(path, name + ": more than 4 dimensions");
    NamedTensor tensor;
    int64_t numel = 1;
    for (uint32_t d = 0; d < ndim; ++d) {
      tensor.shape.push_back(reader.Get<int64_t>());
      if (tensor.shape.back() < 0 || tensor.shape.back() > (1 << 24)) {
        FailAt(path, name + ": bad dimension");
      }
      // Checked per factor: four dimensions of 2^24 would overflow int64.
      numel *= tensor.shape.back();
      if (numel > (int64_t(1) << 28)) FailAt(path, name + ": too large");
    }
    // Before allocating: a small file must not reserve a gigabyte.
    if (size_t(numel) > reader.Remaining() / sizeof(float)) {
      FailAt(path, name + ": truncated LPIPS weights file");
    }
    tensor.values.resize(size_t(numel));
    reader.Read(tensor.values.data(), size_t(numel) * sizeof(float));
    tensors[name] = std::move(tensor);
  }
  if (!reader.AtEnd()) FailAt(path, "bytes after the last tensor");
  return tensors;
}

const std::vector<float>& Take(const std::string& path,
                               const std::map<std::string, NamedTensor>& all,
                               const std::string& name,
                               const std::vector<int64_t>& shape) {
  const auto it = all.find(name);
  if (it == all.end()) FailAt(path, "missing tensor " + name);
  if (it->second.shape != shape) {
    FailAt(path, name + " has the wrong shape");
  }
  return it->second.values;
}

// Divides each pixel's channel vector by its L2 norm (+1e-10), in place.
void NormalizeChannels(Tensor* x) {
  const size_t hw = x->PlaneSize();
  for (size_t i = 0; i < hw; ++i) {
    double sum = 0;
    for (int c = 0; c < x->c; ++c)
      sum += double(x->Plane(0, c)[i]) * x->Plane(0, c)[i];
    const float inv = float(1.0 / (std::sqrt(sum) + 1e-10));
    for (int c = 0; c < x->c; ++c) x->Plane(0, c)[i] *= inv;
  }
}

}  // namespace

void MaxPool2x2Forward(const Tensor& x, Tensor* y) {
  y->Resize(x.n, x.c, x.h / 2, x.w / 2);
  for (int b = 0; b < x.n; ++b) {
    for (int c = 0; c < x.c; ++c) {
      const float* in = x.Plane(b, c);
      float* out = y->Plane(b, c);
      for (int oy = 0; oy < y->h; ++oy) {
        const float* r0 = in + size_t(2 * oy) * x.w;
        const float* r1 = r0 + x.w;
        for (int ox = 0; ox < y->w; ++ox) {
          out[size_t(oy) * y->w + ox] =
              std::max(std::max(r0[2 * ox], r0[2 * ox + 1]),
                       std::max(r1[2 * ox], r1[2 * ox + 1]));
        }
      }
    }
  }
}

std::unique_ptr<Lpips> Lpips::Load(const std::string& path) {
  const std::map<std::string, NamedTensor> all = ReadTensors(path);
  std::unique_ptr<Lpips> lpips(new Lpips());
  const std::vector<float>& shift = Take(path, all, "scaling.shift", {3});
  const std::vector<float>& scale = Take(path, all, "scaling.scale", {3});
  for (int c = 0; c < 3; ++c) {
    lpips->shift_[c] = shift[c];
    lpips->scale_[c] = scale[c];
    if (!(scale[c] != 0)) FailAt(path, "scaling.scale has a zero");
  }
  std::mt19937 unused_init(0);
  int in = 3;
  for (int k = 0; k < 13; ++k) {
    const std::string name = "features." + std::to_string(kConvIndices[k]);
    const int out = kConvWidths[k];
    auto conv = std::make_unique<Conv2d>(name, in, out, 3, &unused_init);
    conv->weight.value = Take(path, all, name + ".weight", {out, in, 3, 3});
    conv->bias.value = Take(path, all, name + ".bias", {out});
    lpips->convs_.push_back(std::move(conv));
    in = out;
  }
  for (int l = 0; l < 5; ++l) {
    lpips->heads_[l] = Take(path, all, "lin" + std::to_string(l) + ".weight",
                            {1, kTapChannels[l], 1, 1});
  }
  return lpips;
}

std::unique_ptr<Lpips> Lpips::WithRandomWeights(uint32_t seed) {
  std::unique_ptr<Lpips> lpips(new Lpips());
  lpips->shift_ = {0.f, 0.f, 0.f};
  lpips->scale_ = {0.5f, 0.5f, 0.5f};
  std::mt19937 rng(seed);
  int in = 3;
  for (int k = 0; k < 13; ++k) {
    lpips->convs_.push_back(
        std::make_unique<Conv2d>("features." + std::to_string(kConvIndices[k]),
                                 in, kConvWidths[k], 3, &rng));
    in = kConvWidths[k];
  }
  std::uniform_real_distribution<float> positive(0.f, 1.f);
  for (int l = 0; l < 5; ++l) {
    lpips->heads_[l].resize(kTapChannels[l]);
    for (float& w : lpips->heads_[l]) w = positive(rng);
  }
  return lpips;
}

Lpips::Features Lpips::Extract(const ImageRGB& image) {
  if (image.width < 16 || image.height < 16) {
    Fail("LPIPS: image " + std::to_string(image.width) + "x" +
         std::to_string(image.height) + " is smaller than 16x16");
  }
  Tensor x(1, 3, image.height, image.width), y;
  for (int c = 0; c < 3; ++c) {
    float* plane = x.Plane(0, c);
    for (size_t i = 0; i < x.PlaneSize(); ++i) {
      const float v = 2.f * std::clamp(image.data[i * 3 + c], 0.f, 1.f) - 1.f;
      plane[i] = (v - shift_[c]) / scale_[c];
    }
  }
  Features features;
  int conv = 0;
  for (int block = 0; block < 5; ++block) {
    if (block > 0) {
      MaxPool2x2Forward(x, &y);
      std::swap(x, y);
    }
    for (int k = 0; k < kBlockConvs[block]; ++k) {
      convs_[conv++]->Forward(x, &y);
      ReluForward(&y);
      std::swap(x, y);
    }
    features.taps[block] = x;
    NormalizeChannels(&features.taps[block]);
  }
  return features;
}

double Lpips::Distance(const Features& a, const Features& b) const {
  double total = 0;
  for (int l = 0; l < 5; ++l) {
    const Tensor& fa = a.taps[l];
    const Tensor& fb = b.taps[l];
    if (!fa.SameShape(fb)) Fail("LPIPS: images of different sizes");
    double sum = 0;
    for (int c = 0; c < fa.c; ++c) {
      const float* pa = fa.Plane(0, c);
      const float* pb = fb.Plane(0, c);
      double channel = 0;
      for (size_t i = 0; i < fa.PlaneSize(); ++i) {
        const double d = double(pa[i]) - pb[i];
        channel += d * d;
      }
      sum += heads_[l][c] * channel;
    }
    total += sum / double(fa.PlaneSize());
  }
  return total;
}

double Lpips::Distance(const ImageRGB& a, const ImageRGB& b) {
  if (a.width != b.width || a.height != b.height) {
    Fail("LPIPS: images of different sizes");
  }
  return Distance(Extract(a), Extract(b));
}

}  // namespace watergs
