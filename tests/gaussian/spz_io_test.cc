// Tests of the .spz reader and writer: values of hand-built files (the
// format's fixed-point positions, 8-bit alphas, colours, log-scales, both
// rotation encodings and SH), round-trip error bounds from each attribute's
// quantisation step, and one-line refusals of truncated and corrupt files.
#include "gaussian/formats/spz_io.h"

#include <gtest/gtest.h>
#include <zlib.h>
#include <zstd.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "tests/common/refusal.h"

namespace watergs {
namespace {

constexpr double kShC0 = 0.28209479177387814;

std::string Gzip(const std::string& raw) {
  z_stream z{};
  EXPECT_EQ(
      deflateInit2(&z, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY),
      Z_OK);
  std::string out(deflateBound(&z, raw.size()) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
  z.avail_in = uInt(raw.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = uInt(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(out.size() - z.avail_out);
  deflateEnd(&z);
  return out;
}

void PutU32(uint32_t v, std::string* out) {
  for (int k = 0; k < 4; ++k) out->push_back(char(v >> (8 * k)));
}

std::string Header(uint32_t version, uint32_t n, int sh_degree,
                   int fractional_bits, int flags = 0) {
  std::string h = "NGSP";
  PutU32(version, &h);
  PutU32(n, &h);
  h += char(sh_degree);
  h += char(fractional_bits);
  h += char(flags);
  h += '\0';
  return h;
}

GaussianModel Decode(const std::string& bytes, SpzInfo* info = nullptr) {
  return DecodeSpz("test.spz", reinterpret_cast<const uint8_t*>(bytes.data()),
                   bytes.size(), info);
}

// The one-line error for `bytes` (tests/common/refusal.h).
std::string Refusal(const std::string& bytes) {
  return testing::Refusal("test.spz", [&] { Decode(bytes); });
}

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed,
                          double min_abs_w = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (float& v : m.means) v = 100.f * u(rng);
  for (float& v : m.log_scales) v = -2.f + 7.f * u(rng);  // [-9, 5]
  for (float& v : m.opacity_logits) v = 6.f * u(rng);
  for (float& v : m.sh_dc) v = 3.f * u(rng);
  for (float& v : m.sh_rest) v = 0.95f * u(rng);
  for (size_t i = 0; i < n; ++i) {
    float* q = &m.quats[4 * i];
    double norm = 0;
    do {
      for (int k = 0; k < 4; ++k) q[k] = u(rng);
      norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    } while (norm < 0.1 || std::abs(q[0]) / norm < min_abs_w);
    for (int k = 0; k < 4; ++k) q[k] *= 2.5f;  // not normalised on purpose
  }
  return m;
}

// Largest component difference of two quaternions after normalising and
// aligning signs (q and -q are one rotation).
double QuatError(const float* a, const float* b) {
  double na = 0, nb = 0, dot = 0;
  for (int k = 0; k < 4; ++k) {
    na += a[k] * a[k];
    nb += b[k] * b[k];
    dot += a[k] * b[k];
  }
  const double sign = dot < 0 ? -1 : 1;
  double worst = 0;
  for (int k = 0; k < 4; ++k) {
    worst = std::max(
        worst, std::abs(a[k] / std::sqrt(na) - sign * b[k] / std::sqrt(nb)));
  }
  return worst;
}

// The file holds RUB axes; the model gets RDF: y and z of positions and
// quaternions negated, SH coefficients signed by parity (degree 1: y z x ->
// - - +; degree 2: xy yz zz xz xx-yy -> - + + - +).
TEST(SpzIo, DecodesHandBuiltVersion3Values) {
  std::string raw = Header(3, 2, 1, 12);
  // Positions, 24-bit little-endian two's complement, 12 fractional bits.
  raw += std::string("\x00\x18\x00", 3);  // 6144 / 4096 = 1.5
  raw += std::string("\x00\xdc\xff", 3);  // -9216 / 4096 = -2.25
  raw += std::string("\x00\x00\x00", 3);
  raw += std::string("\x01\x00\x00", 3);              // 1 / 4096
  raw += std::string("\xff\xff\x7f", 3);              // 2^23 - 1
  raw += std::string("\x00\x00\x80", 3);              // -2^23 = -2048
  raw += std::string("\x00\xbf", 2);                  // alphas 0 and 191
  raw += std::string("\x80\xff\x00\x80\x80\x80", 6);  // colours
  raw += std::string("\xa0\x00\xff\xa0\xa0\xa0", 6);  // scales
  PutU32(3u << 30, &raw);  // w largest, x y z = 0: the identity
  // x largest (index 0 in the top 2 bits), then y z w from the high bits
  // down, each a sign bit and 9 bits of |v| / sqrt(1/2) * 511: y -100, z
  // 200, w 361.
  PutU32(0u << 30 | (512u | 100u) << 20 | 200u << 10 | 361u, &raw);
  raw += std::string("\x80\x00\xff\xc0\x80\x80\x80\x80\x80", 9);
  raw += std::string("\x80\x80\x80\x80\x80\x80\x80\x80\x40", 9);
  SpzInfo info;
  const GaussianModel m = Decode(Gzip(raw), &info);
  EXPECT_EQ(info.version, 3);
  EXPECT_EQ(info.fractional_bits, 12);
  ASSERT_EQ(m.size(), 2u);
  ASSERT_EQ(m.sh_degree, 1);
  const float means[] = {1.5f,  2.25f, -0.f, 1.f / 4096, -8388607.f / 4096,
                         2048.f};
  for (int k = 0; k < 6; ++k) EXPECT_FLOAT_EQ(m.means[k], means[k]) << k;
  EXPECT_EQ(m.opacity_logits[0], -kOpacityLogitLimit);  // alpha 0: not -Inf
  EXPECT_NEAR(m.opacity_logits[1], std::log(191.0 / 64.0), 1e-6);
  EXPECT_NEAR(m.sh_dc[0], (128 / 255.0 - 0.5) / 0.15, 1e-6);
  EXPECT_NEAR(m.sh_dc[1], 0.5 / 0.15, 1e-6);
  EXPECT_NEAR(m.sh_dc[2], -0.5 / 0.15, 1e-6);
  EXPECT_FLOAT_EQ(m.log_scales[0], 0.f);  // 160 / 16 - 10
  EXPECT_FLOAT_EQ(m.log_scales[1], -10.f);
  EXPECT_FLOAT_EQ(m.log_scales[2], 255 / 16.f - 10);
  const float identity[] = {1, 0, 0, 0};
  for (int k = 0; k < 4; ++k) EXPECT_FLOAT_EQ(m.quats[k], identity[k]);
  const double y = -std::sqrt(0.5) * 100 / 511, z = std::sqrt(0.5) * 200 / 511,
               w = std::sqrt(0.5) * 361 / 511;
  const double x = std::sqrt(1 - y * y - z * z - w * w);
  const double second[] = {w, x, -y, -z};  // RDF: y and z negated
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(m.quats[4 + k], second[k], 1e-6);
  // SH bytes: (b - 128) / 128, coefficient-major with rgb inner, as the
  // model keeps them.
  // Coefficients 0 and 1 (y and z) change sign, 2 (x) does not.
  EXPECT_FLOAT_EQ(m.sh_rest[0], 0.f);
  EXPECT_FLOAT_EQ(m.sh_rest[1], 1.f);
  EXPECT_FLOAT_EQ(m.sh_rest[2], -127 / 128.f);
  EXPECT_FLOAT_EQ(m.sh_rest[3], -0.5f);
  EXPECT_FLOAT_EQ(m.sh_rest[17], -0.5f);
}

TEST(SpzIo, ShSignsFollowTheAxisFlipForEveryCoefficient) {
  // One Gaussian, degree 3, every SH byte 192 (+0.5): the decoded signs are
  // the parities of the 15 basis functions under (x, -y, -z).
  std::string raw = Header(3, 1, 3, 12);
  raw += std::string(9, '\0') + "\x80" + std::string(6, '\x80');
  PutU32(3u << 30, &raw);
  raw += std::string(45, '\xc0');
  const GaussianModel m = Decode(Gzip(raw));
  const float signs[15] = {-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1};
  for (int j = 0; j < 15; ++j) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(m.sh_rest[3 * j + c], 0.5f * signs[j]) << j;
    }
  }
  // The writer applies the same flip: the bytes come back as 192.
  const GaussianModel reread = Decode(EncodeSpz(m));
  EXPECT_EQ(reread.sh_rest, m.sh_rest);
}

TEST(SpzIo, DecodesVersion2Rotations) {
  std::string raw = Header(2, 1, 0, 12);
  raw += std::string(9, '\0') + "\xff" + std::string(3, '\x80') +
         std::string(3, '\xa0');
  // x y z bytes: (b / 127.5) - 1; w = sqrt(1 - |xyz|^2).
  raw += std::string("\xbf\x40\x80", 3);
  const GaussianModel m = Decode(Gzip(raw));
  const double x = 191 / 127.5 - 1, y = 64 / 127.5 - 1, z = 128 / 127.5 - 1;
  EXPECT_NEAR(m.quats[1], x, 1e-6);
  EXPECT_NEAR(m.quats[2], -y, 1e-6);  // RUB to RDF
  EXPECT_NEAR(m.quats[3], -z, 1e-6);
  EXPECT_NEAR(m.quats[0], std::sqrt(1 - x * x - y * y - z * z), 1e-6);
  EXPECT_EQ(m.opacity_logits[0], kOpacityLogitLimit);  // alpha 255
}

// Bounds from the quantisation steps: positions 2^-12 (error 2^-13),
// log-scales 1/16, alpha 1/255, colour 1/(255 * 0.15), SH degree 1 a
// bucket of 8/128 (error 4.5/128 with the rounding before it) and 16/128
// above (8.5/128); rotations: the three stored components 1/511 * sqrt(1/2)
// (error 6.9e-4), the largest derived from them (up to 3 times that).
void ExpectRoundTripWithinSteps(int version) {
  const GaussianModel in = RandomModel(500, 3, 7, version == 2 ? 0.5 : 0);
  SpzInfo info;
  const std::string bytes = EncodeSpz(in, {version});
  const GaussianModel out = Decode(bytes, &info);
  EXPECT_EQ(info.version, version);
  EXPECT_EQ(info.fractional_bits, 12);
  ASSERT_EQ(out.size(), in.size());
  ASSERT_EQ(out.sh_degree, 3);
  EXPECT_EQ(out.CountNonFinite(), 0u);
  double worst[6] = {};
  for (size_t i = 0; i < in.means.size(); ++i) {
    worst[0] = std::max(worst[0], double(std::abs(in.means[i] - out.means[i])));
    worst[1] = std::max(worst[1],
                        double(std::abs(in.log_scales[i] - out.log_scales[i])));
    worst[2] = std::max(worst[2], double(std::abs(in.sh_dc[i] - out.sh_dc[i])));
  }
  for (size_t i = 0; i < in.size(); ++i) {
    worst[3] = std::max(worst[3], std::abs(Sigmoid(in.opacity_logits[i]) -
                                           Sigmoid(out.opacity_logits[i])));
    worst[4] =
        std::max(worst[4], QuatError(&in.quats[4 * i], &out.quats[4 * i]));
  }
  double worst_sh1 = 0, worst_sh_rest = 0;
  for (size_t i = 0; i < in.sh_rest.size(); ++i) {
    const double e = std::abs(in.sh_rest[i] - out.sh_rest[i]);
    const bool degree1 = i % in.sh_rest_stride() < 9;
    (degree1 ? worst_sh1 : worst_sh_rest) =
        std::max(degree1 ? worst_sh1 : worst_sh_rest, e);
  }
  EXPECT_LE(worst[0], std::ldexp(1.0, -13) + 1e-5);
  EXPECT_LE(worst[1], 1 / 32.0 + 1e-6);
  EXPECT_LE(worst[2], 0.5 / (255 * 0.15) + 1e-6);
  EXPECT_LE(worst[3], 0.5 / 255 + 1e-6);
  EXPECT_LE(worst[4], version == 3 ? 2.2e-3 : 0.013);
  EXPECT_LE(worst_sh1, 4.5 / 128 + 1e-6);
  EXPECT_LE(worst_sh_rest, 8.5 / 128 + 1e-6);
  // The bounds are not vacuous: quantisation does move values.
  EXPECT_GT(worst[0], 1e-5);
  EXPECT_GT(worst_sh_rest, 4.0 / 128);
}

TEST(SpzIo, Version3RoundTripWithinQuantisationSteps) {
  ExpectRoundTripWithinSteps(3);
}

TEST(SpzIo, Version2RoundTripWithinQuantisationSteps) {
  ExpectRoundTripWithinSteps(2);
}

TEST(SpzIo, FewerFractionalBitsForLargeScenes) {
  GaussianModel in = RandomModel(10, 0, 3);
  in.means[4] = 5000.f;  // 5000 * 2^11 > 2^23: 10 bits
  SpzInfo info;
  const GaussianModel out = Decode(EncodeSpz(in), &info);
  EXPECT_EQ(info.fractional_bits, 10);
  for (size_t i = 0; i < in.means.size(); ++i) {
    EXPECT_LE(std::abs(in.means[i] - out.means[i]), std::ldexp(1.0, -11));
  }
}

TEST(SpzIo, RefusesTruncatedAndCorruptFiles) {
  const std::string good = EncodeSpz(RandomModel(200, 1, 4));
  EXPECT_NE(Refusal(good.substr(0, good.size() / 2)).find("truncated"),
            std::string::npos);
  EXPECT_NE(Refusal(good.substr(0, 12)).find("truncated SPZ header"),
            std::string::npos);
  EXPECT_NE(Refusal(good.substr(0, good.size() - 4)).find("truncated"),
            std::string::npos);
  std::string crc = good;
  crc[crc.size() - 6] ^= 0x55;  // the CRC32 trailer
  EXPECT_NE(Refusal(crc).find("corrupt gzip data"), std::string::npos);
  for (size_t at : {size_t(20), good.size() / 3, good.size() / 2}) {
    std::string flipped = good;
    flipped[at] ^= 0xff;
    Refusal(flipped);
  }
  EXPECT_NE(Refusal("").find("no gzip signature"), std::string::npos);
  EXPECT_NE(Refusal(Gzip("hello, not a splat")).find("not SPZ"),
            std::string::npos);
}

TEST(SpzIo, RefusesUnsupportedHeaders) {
  EXPECT_NE(Refusal(Header(4, 0, 0, 12)).find("truncated SPZ version 4"),
            std::string::npos);
  EXPECT_NE(Refusal(Header(3, 0, 0, 12) + std::string(16, '\0'))
                .find("uncompressed NGSP stream of version 3"),
            std::string::npos);
  EXPECT_NE(Refusal(Gzip(Header(4, 0, 0, 12))).find("version 4 inside gzip"),
            std::string::npos);
  EXPECT_NE(Refusal(Gzip(Header(5, 0, 0, 12))).find("SPZ version 5"),
            std::string::npos);
  EXPECT_NE(Refusal(Gzip(Header(1, 0, 0, 12))).find("SPZ version 1"),
            std::string::npos);
  EXPECT_NE(Refusal(Gzip(Header(3, 0, 4, 12))).find("SH degree 4"),
            std::string::npos);
  EXPECT_NE(Refusal(Gzip(Header(3, 0, 0, 12, 2))).find("extensions"),
            std::string::npos);
  // A count the data does not hold is refused before it is allocated.
  EXPECT_NE(Refusal(Gzip(Header(3, 4000000000u, 3, 12))).find("truncated"),
            std::string::npos);
  // An empty model is valid.
  EXPECT_EQ(Decode(Gzip(Header(3, 0, 2, 12))).size(), 0u);
}

// Version 4: a plaintext header with the table of contents' offset, the
// table (compressed and uncompressed size of each stream) and each
// attribute stream compressed with zstd. The same attributes as a version
// 3 file decode to the same model; extension records before the table are
// skipped.
std::string Version4(const std::string& v3_raw, uint32_t n, int sh_degree,
                     const std::string& extension = "") {
  const size_t dim = 3 * (NumShCoeffs(sh_degree) - 1);
  const size_t sizes[6] = {9 * n, n, 3 * n, 3 * n, 4 * n, dim * n};
  const int streams = dim > 0 ? 6 : 5;
  std::string out = "NGSP";
  PutU32(4, &out);
  PutU32(n, &out);
  out += char(sh_degree);
  out += char(12);
  out += char(extension.empty() ? 0 : 2);
  out += char(streams);
  PutU32(uint32_t(32 + extension.size()), &out);
  out += std::string(12, '\0');
  out += extension;
  std::string toc, body;
  size_t at = 16;  // after the version 3 header
  for (int s = 0; s < streams; ++s) {
    const std::string plain = v3_raw.substr(at, sizes[s]);
    at += sizes[s];
    std::string packed(ZSTD_compressBound(plain.size()), '\0');
    packed.resize(ZSTD_compress(packed.data(), packed.size(), plain.data(),
                                plain.size(), 3));
    for (uint64_t v : {uint64_t(packed.size()), uint64_t(plain.size())}) {
      PutU32(uint32_t(v), &toc);
      PutU32(uint32_t(v >> 32), &toc);
    }
    body += packed;
  }
  return out + toc + body;
}

TEST(SpzIo, Version4StreamsDecodeAsVersion3) {
  for (int degree : {0, 2}) {
    const GaussianModel model = RandomModel(300, degree, 12);
    // The version 3 bytes, inflated.
    const std::string gz = EncodeSpz(model);
    z_stream z{};
    ASSERT_EQ(inflateInit2(&z, 16 + MAX_WBITS), Z_OK);
    std::string raw(1 << 20, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(gz.data()));
    z.avail_in = uInt(gz.size());
    z.next_out = reinterpret_cast<Bytef*>(raw.data());
    z.avail_out = uInt(raw.size());
    ASSERT_EQ(inflate(&z, Z_FINISH), Z_STREAM_END);
    raw.resize(raw.size() - z.avail_out);
    inflateEnd(&z);
    const GaussianModel v3 = Decode(gz);
    SpzInfo info;
    const std::string v4 = Version4(raw, 300, degree, "ext-record");
    const GaussianModel m = Decode(v4, &info);
    EXPECT_EQ(info.version, 4);
    EXPECT_EQ(m.sh_degree, degree);
    EXPECT_EQ(m.means, v3.means);
    EXPECT_EQ(m.quats, v3.quats);
    EXPECT_EQ(m.sh_rest, v3.sh_rest);
    EXPECT_EQ(m.opacity_logits, v3.opacity_logits);
    // Cut, corrupted or with a stream size that disagrees with the count.
    EXPECT_NE(Refusal(v4.substr(0, v4.size() - 7)).find("truncated"),
              std::string::npos);
    // zstd frames carry no checksum here: a flipped byte may decode to
    // other values, but never to a crash or a non-finite value.
    std::string corrupt = v4;
    corrupt[corrupt.size() - 40] ^= 0x5a;
    try {
      EXPECT_EQ(Decode(corrupt).CountNonFinite(), 0u);
    } catch (const Error&) {
    }
    corrupt = v4;
    corrupt[v4.find("ext-record") + 10 + 5 * 16 + 6] ^= 0x5a;  // a frame header
    Refusal(corrupt);
    std::string wrong = v4;
    wrong[32 + 10 + 8] ^= 1;  // uncompressed size of the positions
    EXPECT_NE(Refusal(wrong).find("attribute stream 0 holds"),
              std::string::npos);
  }
}

TEST(SpzIo, WriterRefusesNonFiniteModels) {
  GaussianModel in = RandomModel(3, 0, 5);
  in.means[2] = std::nanf("");
  EXPECT_THROW(EncodeSpz(in), Error);
  EXPECT_THROW(EncodeSpz(RandomModel(3, 0, 5), {4}), Error);
}

}  // namespace
}  // namespace watergs
