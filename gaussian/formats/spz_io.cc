// .spz reading and writing (see spz_io.h for the layout).
#include "gaussian/formats/spz_io.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <vector>

#include "gaussian/formats/codec_util.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr uint32_t kMagic = 0x5053474e;  // "NGSP" little-endian
constexpr size_t kHeaderBytes = 16;
// SPZ's colour scale: DC * 0.15 + 0.5 keeps out-of-gamut base colours.
constexpr double kColorScale = 0.15;
constexpr double kSqrt1_2 = 0.70710678118654752440;
constexpr uint8_t kFlagAntialiased = 0x1;
constexpr uint8_t kFlagExtensions = 0x2;
// Bytes inflated per step, so that memory follows the data actually present
// rather than the count a (possibly corrupt) header claims.
constexpr size_t kInflateStep = size_t(16) << 20;

// Inflates a gzip stream step by step.
class GzipReader {
 public:
  GzipReader(const std::string& name, const uint8_t* data, size_t size)
      : name_(name), next_(data), left_(size) {
    if (inflateInit2(&z_, 16 + MAX_WBITS) != Z_OK) {
      FailAt(name_, "cannot start zlib");
    }
  }
  ~GzipReader() { inflateEnd(&z_); }
  GzipReader(const GzipReader&) = delete;
  GzipReader& operator=(const GzipReader&) = delete;

  // Appends up to `n` inflated bytes to `out`; fewer only at the end of the
  // stream or of the input. Throws Error for corrupt data. Inflates through
  // a small buffer, so that `out` grows with the data present, not with the
  // n a corrupt header asks for.
  size_t Read(size_t n, std::vector<uint8_t>* out) {
    uint8_t buffer[1 << 16];
    size_t produced = 0;
    while (produced < n && !ended_) {
      if (z_.avail_in == 0 && left_ > 0) {
        const size_t feed = std::min<size_t>(left_, UINT_MAX);
        z_.next_in = const_cast<Bytef*>(next_);
        z_.avail_in = static_cast<uInt>(feed);
        next_ += feed;
        left_ -= feed;
      }
      const size_t want = std::min<size_t>(n - produced, sizeof buffer);
      z_.next_out = buffer;
      z_.avail_out = static_cast<uInt>(want);
      const int res = inflate(&z_, Z_NO_FLUSH);
      const size_t got = want - z_.avail_out;
      out->insert(out->end(), buffer, buffer + got);
      produced += got;
      if (res == Z_STREAM_END) {
        ended_ = true;
      } else if (res == Z_BUF_ERROR || (res == Z_OK && z_.avail_in == 0 &&
                                        left_ == 0 && z_.avail_out > 0)) {
        break;  // input exhausted: the caller reports what is missing
      } else if (res != Z_OK) {
        FailAt(name_, std::string("corrupt gzip data (zlib: ") +
                          Printable(z_.msg ? z_.msg : zError(res)) + ")");
      }
    }
    return produced;
  }

  // True once the gzip stream's end (and its CRC check) has been reached.
  bool ended() const { return ended_; }

 private:
  std::string name_;
  z_stream z_{};
  const uint8_t* next_;
  size_t left_;
  bool ended_ = false;
};

std::string Gzip(const std::string& raw) {
  z_stream z{};
  if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 16 + MAX_WBITS, 9,
                   Z_DEFAULT_STRATEGY) != Z_OK) {
    Fail("SPZ: cannot start zlib");
  }
  std::string out;
  std::vector<char> buffer(1 << 16);
  size_t fed = 0;
  int res = Z_OK;
  while (res != Z_STREAM_END) {
    if (z.avail_in == 0 && fed < raw.size()) {
      const size_t feed = std::min<size_t>(raw.size() - fed, UINT_MAX);
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()) + fed);
      z.avail_in = static_cast<uInt>(feed);
      fed += feed;
    }
    z.next_out = reinterpret_cast<Bytef*>(buffer.data());
    z.avail_out = static_cast<uInt>(buffer.size());
    res = deflate(&z, fed == raw.size() ? Z_FINISH : Z_NO_FLUSH);
    if (res != Z_OK && res != Z_STREAM_END && res != Z_BUF_ERROR) {
      deflateEnd(&z);
      Fail("SPZ: zlib deflate failed");
    }
    out.append(buffer.data(), buffer.size() - z.avail_out);
  }
  deflateEnd(&z);
  return out;
}

// SH coefficients per channel above degree 0.
int ShDim(int degree) { return NumShCoeffs(degree) - 1; }

// SPZ stores the RUB axes (y up, z back); 3DGS PLYs are RDF (y down, z
// forward). The change (x, y, z) -> (x, -y, -z) is a half turn about x: it
// negates the y and z of positions and of quaternions, and each real SH
// basis function (3DGS order) keeps or flips its sign with the parity of
// its y and z powers: degree 1 y z x; degree 2 xy yz zz xz xx-yy; degree 3
// y(3xx-yy) xyz y(4zz-xx-yy) z(2zz-3xx-3yy) x(4zz-xx-yy) z(xx-yy)
// x(xx-3yy). It is its own inverse, so reading and writing use it alike.
constexpr float kAxisFlipSh[15] = {-1, -1, 1,  -1, 1, 1,  -1, 1,
                                   -1, 1,  -1, -1, 1, -1, 1};

// Model quaternion (w, x, y, z) in RDF from SPZ's (x, y, z, w) in RUB.
void StoreQuat(const std::array<double, 4>& xyzw, float* q) {
  q[0] = float(xyzw[3]);
  q[1] = float(xyzw[0]);
  q[2] = float(-xyzw[1]);
  q[3] = float(-xyzw[2]);
}

void DecodeRotationV2(const uint8_t* r, float* q) {
  std::array<double, 4> v{};
  double sum = 0;
  for (int k = 0; k < 3; ++k) {
    v[k] = r[k] / 127.5 - 1.0;
    sum += v[k] * v[k];
  }
  v[3] = std::sqrt(std::max(0.0, 1.0 - sum));
  StoreQuat(v, q);
}

void DecodeRotationV3(const uint8_t* r, float* q) {
  uint32_t comp = codec::LoadU32(r);
  const int largest = int(comp >> 30);
  std::array<double, 4> v{};
  double sum = 0;
  for (int k = 3; k >= 0; --k) {
    if (k == largest) continue;
    const double mag = kSqrt1_2 * double(comp & 511u) / 511.0;
    v[k] = (comp >> 9) & 1u ? -mag : mag;
    comp >>= 10;
    sum += v[k] * v[k];
  }
  v[largest] = std::sqrt(std::max(0.0, 1.0 - sum));
  StoreQuat(v, q);
}

// SPZ's (x, y, z, w) in RUB of the normalised model quaternion.
std::array<double, 4> Xyzw(const float* q) {
  const auto n = codec::Normalized(q);
  return {n[1], -n[2], -n[3], n[0]};
}

void EncodeRotationV2(const float* q, std::string* out) {
  auto v = Xyzw(q);
  const double sign = v[3] < 0 ? -1 : 1;
  for (int k = 0; k < 3; ++k) {
    out->push_back(char(codec::RoundClamp(sign * v[k] * 127.5 + 127.5, 255)));
  }
}

void EncodeRotationV3(const float* q, std::string* out) {
  const auto v = Xyzw(q);
  int largest = 0;
  for (int k = 1; k < 4; ++k) {
    if (std::abs(v[k]) > std::abs(v[largest])) largest = k;
  }
  const bool negate = v[largest] < 0;
  uint32_t comp = uint32_t(largest);
  for (int k = 0; k < 4; ++k) {
    if (k == largest) continue;
    const uint32_t negbit = (v[k] < 0) != negate ? 1u : 0u;
    const uint32_t mag =
        codec::RoundClamp(511.0 * std::abs(v[k]) / kSqrt1_2, 511);
    comp = comp << 10 | negbit << 9 | mag;
  }
  codec::AppendU32(comp, out);
}

// SH byte of the reference encoder: x * 128 + 128 rounded, then to the
// nearest multiple of `bucket` (8 for 5 bits, 16 for 4 bits).
uint8_t QuantizeSh(float x, int bucket) {
  const double scaled = std::clamp(double(x) * 128.0, -1e6, 1e6);
  int q = int(std::round(scaled)) + 128;
  q = (q + bucket / 2) / bucket * bucket;
  return uint8_t(std::clamp(q, 0, 255));
}

struct SpzHeader {
  uint32_t version = 0;
  uint64_t n = 0;
  int sh_degree = 0;
  int fractional_bits = 0;
  uint8_t flags = 0;
};

// Attribute bytes of N Gaussians in file order: positions, alphas, colours,
// scales, rotations, SH.
std::array<uint64_t, 6> StreamSizes(const SpzHeader& h) {
  const uint64_t n = h.n;
  return {9 * n,
          n,
          3 * n,
          3 * n,
          (h.version == 2 ? 3 : 4) * n,
          3 * uint64_t(ShDim(h.sh_degree)) * n};
}

void CheckHeader(const std::string& name, const SpzHeader& h) {
  if (h.version < 2 || h.version > 4) {
    FailAt(name, "SPZ version " + std::to_string(h.version) +
                     " is not supported (versions 2, 3 and 4 are)");
  }
  if (h.sh_degree > 3) {
    FailAt(name, "SH degree " + std::to_string(h.sh_degree) +
                     " is not supported (watergs models hold degrees 0-3)");
  }
}

// Versions 2 and 3: one gzip stream of the 16-byte header and the
// attributes.
std::vector<uint8_t> ReadGzipPayload(const std::string& name,
                                     const uint8_t* data, size_t size,
                                     SpzHeader* h) {
  GzipReader gzip(name, data, size);
  std::vector<uint8_t> bytes;
  if (gzip.Read(kHeaderBytes, &bytes) < kHeaderBytes) {
    FailAt(name, "truncated SPZ header (" + std::to_string(bytes.size()) +
                     " of 16 bytes)");
  }
  if (codec::LoadU32(bytes.data()) != kMagic) {
    FailAt(name, "gzip data that is not SPZ (no NGSP magic)");
  }
  h->version = codec::LoadU32(bytes.data() + 4);
  h->n = codec::LoadU32(bytes.data() + 8);
  h->sh_degree = bytes[12];
  h->fractional_bits = bytes[13];
  h->flags = bytes[14];
  CheckHeader(name, *h);
  if (h->version == 4) FailAt(name, "SPZ version 4 inside gzip");
  if (h->flags & kFlagExtensions) {
    FailAt(name,
           "SPZ extensions (flag 0x2) are not supported before "
           "version 4");
  }
  uint64_t payload = 0;
  for (uint64_t s : StreamSizes(*h)) payload += s;
  bytes.clear();
  // Deflate inflates at most 1032:1: a header asking for more than the data
  // can give is refused before any allocation; otherwise one allocation.
  if (payload > uint64_t(size) * 1032 + 64) {
    FailAt(name, "truncated SPZ data: " + std::to_string(h->n) +
                     " Gaussians need " + std::to_string(payload) +
                     " bytes after the header, more than " +
                     std::to_string(size) + " compressed bytes can hold");
  }
  bytes.reserve(size_t(payload));
  while (bytes.size() < payload) {
    const size_t step =
        size_t(std::min<uint64_t>(payload - bytes.size(), kInflateStep));
    if (gzip.Read(step, &bytes) < step) break;
  }
  if (bytes.size() < payload) {
    FailAt(name, "truncated SPZ data: " + std::to_string(h->n) +
                     " Gaussians need " + std::to_string(payload) +
                     " bytes after the header, the stream holds " +
                     std::to_string(bytes.size()));
  }
  // Inflate to the end of the stream (bytes after the attributes are
  // ignored, as the reference reader does) so that zlib checks the CRC: a
  // damaged file is refused rather than read as other values.
  std::vector<uint8_t> rest;
  while (!gzip.ended()) {
    rest.clear();
    if (gzip.Read(1 << 16, &rest) < (1 << 16) && !gzip.ended()) {
      FailAt(name, "truncated gzip stream (no end after the SPZ data)");
    }
  }
  return bytes;
}

uint64_t LoadU64(const uint8_t* p) {
  return uint64_t(codec::LoadU32(p)) | uint64_t(codec::LoadU32(p + 4)) << 32;
}

// Version 4: a 32-byte plaintext header (magic, version, count, SH degree,
// fractional bits, flags, number of streams, byte offset of the table of
// contents), extension records up to that offset (skipped), the table
// (compressed and uncompressed size of each stream, u64 each) and the
// attribute streams, each compressed with zstd on its own.
std::vector<uint8_t> ReadZstdPayload(const std::string& name,
                                     const uint8_t* data, size_t size,
                                     SpzHeader* h) {
  if (size < 32) FailAt(name, "truncated SPZ version 4 header");
  h->version = codec::LoadU32(data + 4);
  h->n = codec::LoadU32(data + 8);
  h->sh_degree = data[12];
  h->fractional_bits = data[13];
  h->flags = data[14];
  const int num_streams = data[15];
  const uint64_t toc = codec::LoadU32(data + 16);
  if (h->version != 4) {
    FailAt(name, "an uncompressed NGSP stream of version " +
                     std::to_string(h->version) +
                     " (only version 4 is stored without gzip)");
  }
  CheckHeader(name, *h);
  const auto sizes = StreamSizes(*h);
  const int needed = sizes[5] > 0 ? 6 : 5;
  if (num_streams != needed && !(num_streams == 6 && needed == 5)) {
    FailAt(name, std::to_string(num_streams) +
                     " attribute streams; SH "
                     "degree " +
                     std::to_string(h->sh_degree) + " needs " +
                     std::to_string(needed));
  }
  if (toc < 32 || toc > size || (size - toc) / 16 < uint64_t(num_streams)) {
    FailAt(name, "table of contents at byte " + std::to_string(toc) +
                     " lies outside the " + std::to_string(size) +
                     "-byte file");
  }
  uint64_t offset = toc + 16 * uint64_t(num_streams);
  uint64_t payload = 0;
  for (uint64_t s : sizes) payload += s;
  // Checked before anything is allocated: each stream's sizes against the
  // count and the file, and a compression ratio zstd can reach.
  std::vector<std::pair<uint64_t, uint64_t>> streams;  // offset, size
  for (int s = 0; s < num_streams; ++s) {
    const uint64_t compressed = LoadU64(data + toc + 16 * s);
    const uint64_t uncompressed = LoadU64(data + toc + 16 * s + 8);
    if (uncompressed != sizes[s]) {
      FailAt(name, "attribute stream " + std::to_string(s) + " holds " +
                       std::to_string(uncompressed) + " bytes; " +
                       std::to_string(h->n) + " Gaussians need " +
                       std::to_string(sizes[s]));
    }
    if (compressed > size - offset) {
      FailAt(name, "truncated SPZ data: attribute stream " + std::to_string(s) +
                       " needs " + std::to_string(compressed) + " bytes, " +
                       std::to_string(size - offset) + " are left");
    }
    if (uncompressed / 40000 > compressed) {
      FailAt(name, "attribute stream " + std::to_string(s) +
                       " claims a compression ratio zstd cannot reach");
    }
    streams.push_back({offset, compressed});
    offset += compressed;
  }
  std::vector<uint8_t> bytes(payload);
  uint64_t at = 0;
  for (int s = 0; s < num_streams && at < payload; ++s) {
    if (sizes[s] == 0) continue;
    const size_t got =
        ZSTD_decompress(bytes.data() + at, sizes[s], data + streams[s].first,
                        streams[s].second);
    if (ZSTD_isError(got)) {
      FailAt(name, "corrupt zstd data in attribute stream " +
                       std::to_string(s) + " (" + ZSTD_getErrorName(got) + ")");
    }
    if (got != sizes[s]) {
      FailAt(name, "attribute stream " + std::to_string(s) + " holds " +
                       std::to_string(got) + " bytes, not " +
                       std::to_string(sizes[s]));
    }
    at += sizes[s];
  }
  return bytes;
}

}  // namespace

GaussianModel DecodeSpz(const std::string& name, const uint8_t* data,
                        size_t size, SpzInfo* info) {
  SpzHeader h;
  std::vector<uint8_t> bytes;
  if (size >= 4 && codec::LoadU32(data) == kMagic) {
    bytes = ReadZstdPayload(name, data, size, &h);
  } else if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b) {
    bytes = ReadGzipPayload(name, data, size, &h);
  } else {
    FailAt(name, "not an SPZ file (no gzip signature or NGSP magic)");
  }
  const uint64_t n = h.n;
  const uint32_t version = h.version;
  const int sh_degree = h.sh_degree;
  const int fractional_bits = h.fractional_bits;
  const uint64_t rotation_bytes = version == 2 ? 3 : 4;
  if (info != nullptr) {
    info->version = int(version);
    info->fractional_bits = fractional_bits;
    info->antialiased = (h.flags & kFlagAntialiased) != 0;
  }

  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(size_t(n));
  const uint8_t* p = bytes.data();
  for (size_t i = 0; i < 3 * n; ++i, p += 3) {
    int32_t fixed = int32_t(p[0] | p[1] << 8 | p[2] << 16);
    if (fixed & 0x800000) fixed -= 1 << 24;
    const double sign = i % 3 == 0 ? 1 : -1;  // RUB to RDF
    model.means[i] = float(sign * std::ldexp(double(fixed), -fractional_bits));
  }
  for (size_t i = 0; i < n; ++i, ++p) {
    model.opacity_logits[i] = AlphaToOpacityLogit(*p / 255.0);
  }
  for (size_t i = 0; i < 3 * n; ++i, ++p) {
    model.sh_dc[i] = float((*p / 255.0 - 0.5) / kColorScale);
  }
  for (size_t i = 0; i < 3 * n; ++i, ++p) {
    model.log_scales[i] = float(*p / 16.0 - 10.0);
  }
  for (size_t i = 0; i < n; ++i, p += rotation_bytes) {
    if (version == 2) {
      DecodeRotationV2(p, &model.quats[4 * i]);
    } else {
      DecodeRotationV3(p, &model.quats[4 * i]);
    }
  }
  // SPZ's SH order (coefficient-major, rgb inner) is the model's.
  const int stride = model.sh_rest_stride();
  for (size_t i = 0; i < model.sh_rest.size(); ++i, ++p) {
    const float sign = kAxisFlipSh[(i % stride) / 3];
    model.sh_rest[i] = sign * float((*p - 128.0) / 128.0);
  }
  return model;
}

std::string EncodeSpz(const GaussianModel& model,
                      const SpzWriteOptions& options) {
  if (options.version != 2 && options.version != 3) {
    Fail("SPZ: cannot write version " + std::to_string(options.version) +
         " (2 and 3 are supported)");
  }
  const size_t bad = model.CountNonFinite();
  if (bad > 0) {
    Fail("SPZ: cannot encode a model with " + std::to_string(bad) +
         " NaN/Inf values");
  }
  const size_t n = model.size();
  if (n > UINT32_MAX) Fail("SPZ: more than 2^32 Gaussians");
  // 12 fractional bits unless the signed 24-bit range [-2^23, 2^23 - 1]
  // would overflow.
  double lo = 0, hi = 0;
  for (size_t i = 0; i < model.means.size(); ++i) {
    const double x = (i % 3 == 0 ? 1 : -1) * double(model.means[i]);
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  const auto fits = [&](int bits) {
    return std::ldexp(hi, bits) < 8388607.5 &&
           std::ldexp(lo, bits) >= -8388608.5;
  };
  int fractional_bits = 12;
  while (fractional_bits > 0 && !fits(fractional_bits)) --fractional_bits;
  if (!fits(fractional_bits)) {
    Fail(
        "SPZ: positions beyond [-8388608, 8388607] cannot be stored in 24 "
        "bits");
  }
  const int dim = ShDim(model.sh_degree);
  std::string raw;
  raw.reserve(kHeaderBytes + n * (20 + 3 * dim));
  codec::AppendU32(kMagic, &raw);
  codec::AppendU32(uint32_t(options.version), &raw);
  codec::AppendU32(uint32_t(n), &raw);
  raw.push_back(char(model.sh_degree));
  raw.push_back(char(fractional_bits));
  raw.push_back(0);  // flags
  raw.push_back(0);  // reserved
  for (size_t i = 0; i < model.means.size(); ++i) {
    const double x = (i % 3 == 0 ? 1 : -1) * double(model.means[i]);
    const int32_t fixed = int32_t(std::lround(std::ldexp(x, fractional_bits)));
    for (int k = 0; k < 3; ++k) raw.push_back(char((fixed >> (8 * k)) & 0xff));
  }
  for (float logit : model.opacity_logits) {
    raw.push_back(
        char(codec::RoundClamp(OpacityLogitToAlpha(logit) * 255, 255)));
  }
  for (float dc : model.sh_dc) {
    raw.push_back(
        char(codec::RoundClamp(dc * (kColorScale * 255) + 127.5, 255)));
  }
  for (float s : model.log_scales) {
    raw.push_back(char(codec::RoundClamp((s + 10.0) * 16.0, 255)));
  }
  for (size_t i = 0; i < n; ++i) {
    if (options.version == 2) {
      EncodeRotationV2(&model.quats[4 * i], &raw);
    } else {
      EncodeRotationV3(&model.quats[4 * i], &raw);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    for (int j = 0; j < dim; ++j) {
      const int bucket = j < 3 ? 8 : 16;  // 5 bits for degree 1, 4 above
      for (int c = 0; c < 3; ++c) {
        raw.push_back(char(QuantizeSh(
            kAxisFlipSh[j] *
                model.sh_rest[i * model.sh_rest_stride() + 3 * j + c],
            bucket)));
      }
    }
  }
  return Gzip(raw);
}

void WriteSpz(const std::string& path, const GaussianModel& model,
              const SpzWriteOptions& options) {
  std::string bytes;
  try {
    bytes = EncodeSpz(model, options);
  } catch (const Error& e) {
    FailAt(path, e.what());
  }
  AtomicWriteFile(path, bytes);
}

}  // namespace watergs
