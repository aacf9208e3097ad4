// Tests of the 3DGS PLY reader/writer: Inria byte layout, byte-identical round
// trips, files from other tools, and refusal of malformed files.
#include "gaussian/formats/ply_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

std::string TempDir() {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_ply_io_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir.string();
}

std::string TempPath(const std::string& name) { return TempDir() + "/" + name; }

std::string ReadAll(const std::string& path) {
  const auto bytes = ReadFileBytes(path);
  return std::string(bytes.begin(), bytes.end());
}

void WriteAll(const std::string& path, const std::string& bytes) {
  AtomicWriteFile(path, bytes);
}

GaussianModel RandomModel(int sh_degree, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 2.f);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (auto* v : {&m.means, &m.log_scales, &m.quats, &m.opacity_logits,
                  &m.sh_dc, &m.sh_rest}) {
    for (float& x : *v) x = normal(rng);
  }
  return m;
}

void AppendFloat(float v, std::string* out) {
  char b[4];
  std::memcpy(b, &v, 4);
  out->append(b, 4);
}

void AppendDouble(double v, std::string* out) {
  char b[8];
  std::memcpy(b, &v, 8);
  out->append(b, 8);
}

// The file Inria's save_ply writes for `m`, built here from the format's
// description rather than through the code under test.
std::string InriaBytes(const GaussianModel& m) {
  const int rest_per_channel = NumShCoeffs(m.sh_degree) - 1;
  std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex " +
                  std::to_string(m.size()) + "\n";
  std::vector<std::string> names = {"x",  "y",      "z",      "nx",    "ny",
                                    "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
  for (int i = 0; i < 3 * rest_per_channel; ++i)
    names.push_back("f_rest_" + std::to_string(i));
  for (const char* n : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0",
                        "rot_1", "rot_2", "rot_3"}) {
    names.push_back(n);
  }
  for (const auto& n : names) s += "property float " + n + "\n";
  s += "end_header\n";
  for (size_t i = 0; i < m.size(); ++i) {
    for (int k = 0; k < 3; ++k) AppendFloat(m.means[3 * i + k], &s);
    for (int k = 0; k < 3; ++k) AppendFloat(0.f, &s);
    for (int k = 0; k < 3; ++k) AppendFloat(m.sh_dc[3 * i + k], &s);
    // Channel-major: all R coefficients, then G, then B.
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < rest_per_channel; ++k) {
        AppendFloat(m.sh_rest[i * m.sh_rest_stride() + 3 * k + c], &s);
      }
    }
    AppendFloat(m.opacity_logits[i], &s);
    for (int k = 0; k < 3; ++k) AppendFloat(m.log_scales[3 * i + k], &s);
    for (int k = 0; k < 4; ++k) AppendFloat(m.quats[4 * i + k], &s);
  }
  return s;
}

void ExpectModelsEqual(const GaussianModel& a, const GaussianModel& b) {
  EXPECT_EQ(a.sh_degree, b.sh_degree);
  EXPECT_EQ(a.means, b.means);
  EXPECT_EQ(a.log_scales, b.log_scales);
  EXPECT_EQ(a.quats, b.quats);
  EXPECT_EQ(a.opacity_logits, b.opacity_logits);
  EXPECT_EQ(a.sh_dc, b.sh_dc);
  EXPECT_EQ(a.sh_rest, b.sh_rest);
}

class PlyDegreeTest : public ::testing::TestWithParam<int> {};

TEST_P(PlyDegreeTest, WritesInriaBytesAndRoundTripsByteIdentically) {
  const int degree = GetParam();
  const GaussianModel model = RandomModel(degree, 37, 100 + degree);
  const std::string expected = InriaBytes(model);
  const std::string inria =
      TempPath("inria_" + std::to_string(degree) + ".ply");
  WriteAll(inria, expected);

  const PlyData data = ReadPly(inria);
  EXPECT_EQ(data.model.sh_degree, degree);
  EXPECT_EQ(data.file_size, expected.size());
  ExpectModelsEqual(data.model, model);

  const std::string copy = TempPath("copy_" + std::to_string(degree) + ".ply");
  WritePly(copy, data.model, data.layout);
  EXPECT_TRUE(ReadAll(copy) == expected)
      << "round trip differs for degree " << degree;

  const std::string fresh =
      TempPath("fresh_" + std::to_string(degree) + ".ply");
  WritePly(fresh, model);
  EXPECT_TRUE(ReadAll(fresh) == expected)
      << "default writer is not Inria's layout";
}

INSTANTIATE_TEST_SUITE_P(ShDegrees, PlyDegreeTest,
                         ::testing::Values(0, 1, 2, 3));

TEST(PlyIo, EmptyModelRoundTrips) {
  GaussianModel model;
  model.sh_degree = 3;
  const std::string path = TempPath("empty.ply");
  WritePly(path, model);
  EXPECT_EQ(ReadAll(path), InriaBytes(model));
  EXPECT_EQ(ReadPly(path).model.size(), 0u);
}

// Another tool's file: no normals, its own property order, x/y/z as double,
// two extra properties, SH degree 1, comments and CRLF header lines.
struct OtherToolFile {
  std::string bytes;
  GaussianModel model;
  std::vector<std::pair<uint8_t, float>>
      extras;  // (label, confidence) per vertex
};

OtherToolFile MakeOtherToolFile(size_t n) {
  OtherToolFile f;
  f.model = RandomModel(1, n, 7);
  const std::string e = "\r\n";
  std::string& s = f.bytes;
  s = "ply" + e + "comment written by some other tool" + e +
      "format binary_little_endian 1.0" + e + "element vertex " +
      std::to_string(n) + e + "property uchar label" + e;
  for (int i = 0; i < 4; ++i)
    s += "property float rot_" + std::to_string(i) + e;
  s += "obj_info between properties" + e;
  for (int i = 0; i < 3; ++i)
    s += "property float scale_" + std::to_string(i) + e;
  for (int i = 8; i >= 0; --i)
    s += "property float f_rest_" + std::to_string(i) + e;
  s += "property float opacity" + e + "property float confidence" + e;
  for (int i = 0; i < 3; ++i)
    s += "property float f_dc_" + std::to_string(i) + e;
  s += "property double x" + e + "property double y" + e + "property double z" +
       e;
  s += "comment last words" + e + "end_header" + e;
  const GaussianModel& m = f.model;
  for (size_t i = 0; i < n; ++i) {
    f.extras.push_back({static_cast<uint8_t>(i * 7 % 256), 0.5f + i});
    s.push_back(static_cast<char>(f.extras.back().first));
    for (int k = 0; k < 4; ++k) AppendFloat(m.quats[4 * i + k], &s);
    for (int k = 0; k < 3; ++k) AppendFloat(m.log_scales[3 * i + k], &s);
    for (int j = 8; j >= 0; --j) {
      const int channel = j / 3, coeff = j % 3;  // f_rest_j, channel-major
      AppendFloat(m.sh_rest[i * 9 + coeff * 3 + channel], &s);
    }
    AppendFloat(m.opacity_logits[i], &s);
    AppendFloat(f.extras.back().second, &s);
    for (int k = 0; k < 3; ++k) AppendFloat(m.sh_dc[3 * i + k], &s);
    for (int k = 0; k < 3; ++k) AppendDouble(m.means[3 * i + k], &s);
  }
  return f;
}

TEST(PlyIo, ReadsOtherOrderMissingNormalsExtrasAndDoubles) {
  const OtherToolFile f = MakeOtherToolFile(11);
  const std::string path = TempPath("other.ply");
  WriteAll(path, f.bytes);
  const PlyData data = ReadPly(path);
  ExpectModelsEqual(data.model, f.model);
  ASSERT_EQ(data.layout.NumExtras(), 2);
  for (size_t i = 0; i < f.extras.size(); ++i) {
    EXPECT_EQ(data.layout.extra_values[2 * i], f.extras[i].first);
    EXPECT_EQ(data.layout.extra_values[2 * i + 1], f.extras[i].second);
  }
  // Written back in its own layout: same bytes, comments and CRLF included.
  const std::string copy = TempPath("other_copy.ply");
  WritePly(copy, data.model, data.layout);
  EXPECT_TRUE(ReadAll(copy) == f.bytes);
}

TEST(PlyIo, RemapExtrasFollowsParentsAfterDensityChange) {
  const OtherToolFile f = MakeOtherToolFile(6);
  const std::string path = TempPath("remap.ply");
  WriteAll(path, f.bytes);
  PlyData data = ReadPly(path);
  // Keep Gaussians 1, 3 and 4; then add a clone of 3 and one brand-new
  // Gaussian.
  GaussianModel edited = data.model;
  edited.Filter({false, true, false, true, true, false});
  edited.AppendFrom(data.model, 3);
  edited.AppendFrom(data.model, 0);
  const std::vector<int64_t> parent = {1, 3, 4, 3, -1};
  PlyLayout layout = data.layout;
  EXPECT_THROW(WritePly(TempPath("stale.ply"), edited, layout), Error);
  EXPECT_FALSE(std::filesystem::exists(TempPath("stale.ply")));
  layout.RemapExtras(parent);
  const std::string out = TempPath("remapped.ply");
  WritePly(out, edited, layout);
  const PlyData back = ReadPly(out);
  ExpectModelsEqual(back.model, edited);
  EXPECT_EQ(back.layout.properties.size(), data.layout.properties.size());
  for (size_t i = 0; i < parent.size(); ++i) {
    const double label = parent[i] < 0 ? 0.0 : f.extras[parent[i]].first;
    const double confidence = parent[i] < 0 ? 0.0 : f.extras[parent[i]].second;
    EXPECT_EQ(back.layout.extra_values[2 * i], label) << i;
    EXPECT_EQ(back.layout.extra_values[2 * i + 1], confidence) << i;
  }
}

TEST(PlyIo, ReadsAsciiAndBigEndian) {
  const GaussianModel model = RandomModel(0, 5, 3);
  const std::string inria = InriaBytes(model);
  const size_t header_end = inria.find("end_header\n") + 11;
  const std::string header = inria.substr(0, header_end);
  const int props = 17;

  std::string big = header;
  big.replace(big.find("binary_little_endian"), 20, "binary_big_endian");
  for (size_t p = header_end; p < inria.size(); p += 4) {
    for (int b = 3; b >= 0; --b) big.push_back(inria[p + b]);
  }
  const std::string big_path = TempPath("big.ply");
  WriteAll(big_path, big);
  ExpectModelsEqual(ReadPly(big_path).model, model);
  const std::string big_copy = TempPath("big_copy.ply");
  WritePly(big_copy, model, ReadPly(big_path).layout);
  EXPECT_TRUE(ReadAll(big_copy) == big);

  std::string ascii = header;
  ascii.replace(ascii.find("binary_little_endian"), 20, "ascii");
  for (size_t p = header_end, k = 0; p < inria.size(); p += 4, ++k) {
    float v;
    std::memcpy(&v, &inria[p], 4);
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.9g", v);
    ascii += buf;
    ascii += (k % props == props - 1) ? "\n" : " ";
  }
  const std::string ascii_path = TempPath("ascii.ply");
  WriteAll(ascii_path, ascii);
  const PlyData data = ReadPly(ascii_path);
  ExpectModelsEqual(data.model, model);
  EXPECT_EQ(data.layout.format, PlyFormat::kAscii);
  // Written back as ascii and read again: same values.
  const std::string ascii_copy = TempPath("ascii_copy.ply");
  WritePly(ascii_copy, data.model, data.layout);
  ExpectModelsEqual(ReadPly(ascii_copy).model, model);
}

// ------------------------------------------------------- malformed files ---

// Expects ReadPly(path) to throw an Error naming the file and containing
// `problem`.
void ExpectRefused(const std::string& path, const std::string& problem,
                   const PlyReadOptions& options = {}) {
  try {
    ReadPly(path, options);
    ADD_FAILURE() << path << " was accepted, expected: " << problem;
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(problem), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

std::string WriteCase(const std::string& name, const std::string& bytes) {
  const std::string path = TempPath(name);
  WriteAll(path, bytes);
  return path;
}

// Replaces the first occurrence of `from` in `s` by `to`.
std::string Replace(std::string s, const std::string& from,
                    const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(PlyIoErrors, MissingFileAndDirectory) {
  ExpectRefused(TempPath("does_not_exist.ply"), "not found");
  ExpectRefused(TempDir(), "directory");
}

TEST(PlyIoErrors, NotAPly) {
  ExpectRefused(WriteCase("empty.bin", ""), "not a PLY");
  ExpectRefused(WriteCase("garbage.bin", "\x89PNG\r\n\x1a\n some image"),
                "not a PLY");
}

TEST(PlyIoErrors, TruncatedHeaderAndData) {
  const std::string good = InriaBytes(RandomModel(2, 20, 5));
  const size_t header_end = good.find("end_header\n");
  ExpectRefused(WriteCase("trunc_header.ply", good.substr(0, header_end - 30)),
                "truncated PLY header");
  ExpectRefused(WriteCase("trunc_data.ply", good.substr(0, good.size() - 3)),
                "20 vertices");
  // Plenty of bytes for 20 vertices, but values for only 10 of them.
  std::string ascii =
      Replace(good.substr(0, header_end + 11), "binary_little_endian", "ascii");
  for (int i = 0; i < 10 * 41; ++i) ascii += "0.123456789 ";
  ExpectRefused(WriteCase("trunc_ascii.ply", ascii), "truncated");
}

TEST(PlyIoErrors, AbsurdVertexCountDoesNotAllocate) {
  const std::string good = InriaBytes(RandomModel(3, 4, 5));
  ExpectRefused(WriteCase("huge.ply", Replace(good, "element vertex 4",
                                              "element vertex 1000000000000")),
                "1000000000000 vertices");
  ExpectRefused(WriteCase("overflow.ply",
                          Replace(good, "element vertex 4",
                                  "element vertex 99999999999999999999999")),
                "bad vertex count");
  ExpectRefused(WriteCase("negative.ply", Replace(good, "element vertex 4",
                                                  "element vertex -4")),
                "bad vertex count");
}

TEST(PlyIoErrors, MissingOrBadProperties) {
  const std::string good = InriaBytes(RandomModel(1, 3, 5));
  ExpectRefused(
      WriteCase("no_opacity.ply", Replace(good, "property float opacity",
                                          "property float opacitx")),
      "missing vertex property opacity");
  ExpectRefused(WriteCase("int_x.ply",
                          Replace(good, "property float x", "property int x")),
                "type int");
  ExpectRefused(
      WriteCase("rest_range.ply", Replace(good, "property float f_rest_8",
                                          "property float f_rest_9")),
      "f_rest_9");
  ExpectRefused(
      WriteCase("rest_count.ply", Replace(good, "property float f_rest_8",
                                          "property float f_rest8")),
      "8 f_rest properties");
  ExpectRefused(WriteCase("dup.ply", Replace(good, "property float nx",
                                             "property float y")),
                "declared twice");
  ExpectRefused(WriteCase("type.ply", Replace(good, "property float nx",
                                              "property half nx")),
                "unknown type 'half'");
}

TEST(PlyIoErrors, UnsupportedStructure) {
  const std::string good = InriaBytes(RandomModel(0, 3, 5));
  ExpectRefused(
      WriteCase("list.ply", Replace(good, "property float nx",
                                    "property list uchar int vertex_indices")),
      "list property");
  ExpectRefused(WriteCase("face.ply", Replace(good, "end_header",
                                              "element face 0\nend_header")),
                "element 'face'");
  ExpectRefused(WriteCase("format.ply", Replace(good, "binary_little_endian",
                                                "binary_middle")),
                "unknown PLY format");
  ExpectRefused(WriteCase("keyword.ply",
                          Replace(good, "end_header", "foo bar\nend_header")),
                "unknown PLY header line");
}

TEST(PlyIoErrors, NonFiniteRefusedByDefaultAndCountedOnRequest) {
  GaussianModel model = RandomModel(1, 10, 5);
  model.means[4] = std::numeric_limits<float>::quiet_NaN();
  model.sh_rest[9 * 3 + 2] = std::numeric_limits<float>::infinity();
  model.opacity_logits[7] = -std::numeric_limits<float>::infinity();
  model.log_scales[5] = std::numeric_limits<float>::infinity();
  const std::string path = WriteCase("nan.ply", InriaBytes(model));
  // The -Inf opacity is read as -20; NaN and the other infinities are not.
  ExpectRefused(path, "3 NaN/Inf values (first: vertex 1, property y)");
  PlyReadOptions allow;
  allow.allow_non_finite = true;
  allow.warnings = nullptr;
  const PlyData data = ReadPly(path, allow);
  EXPECT_EQ(data.non_finite_count, 3u);
  EXPECT_EQ(data.replaced_infinities, 1u);
  EXPECT_TRUE(std::isnan(data.model.means[4]));
  EXPECT_EQ(data.model.opacity_logits[7], -kOpacityLogitLimit);
  EXPECT_EQ(data.model.CountNonFinite(), 3u);
}

// What a quantised file decoded to a PLY legitimately holds (alpha 0 or 1
// as logits -+Inf, scale 0 as log-scale -Inf) is read as what viewers
// render, with one warning line naming the count and the file; NaN in the
// same places is still refused, and +Inf log-scales too.
TEST(PlyIoErrors, InfiniteOpacityAndZeroScaleReadAsWhatViewersRender) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  GaussianModel model = RandomModel(2, 6, 9);
  model.opacity_logits[0] = kInf;
  model.opacity_logits[3] = -kInf;
  model.opacity_logits[4] = -kInf;
  model.log_scales[7] = -kInf;
  const std::string path = WriteCase("inf_opacity.ply", InriaBytes(model));
  std::ostringstream warnings;
  PlyReadOptions options;
  options.warnings = &warnings;
  const PlyData data = ReadPly(path, options);
  EXPECT_EQ(data.replaced_infinities, 4u);
  EXPECT_EQ(data.non_finite_count, 0u);
  EXPECT_EQ(data.model.CountNonFinite(), 0u);
  EXPECT_EQ(data.model.opacity_logits[0], kOpacityLogitLimit);
  EXPECT_EQ(data.model.opacity_logits[3], -kOpacityLogitLimit);
  EXPECT_EQ(data.model.log_scales[7], kLogScaleFloor);
  EXPECT_EQ(data.model.opacity_logits[1], model.opacity_logits[1]);
  // Rendered the same: alpha within 3e-9 of 1 and 0, and below 1/255.
  EXPECT_EQ(float(OpacityLogitToAlpha(data.model.opacity_logits[0])), 1.f);
  EXPECT_LT(OpacityLogitToAlpha(data.model.opacity_logits[3]), 3e-9);
  EXPECT_EQ(warnings.str(),
            "warning: " + path +
                ": 4 infinite opacity logits or log-scales read as what "
                "viewers render (logit +-20 = alpha 0 or 1, log-scale -20 = "
                "flat)\n");
  // Written back and read again: finite, unchanged, no warning.
  const std::string again = TempPath("inf_opacity_again.ply");
  WritePly(again, data.model, data.layout);
  std::ostringstream quiet;
  options.warnings = &quiet;
  EXPECT_EQ(ReadPly(again, options).model.opacity_logits,
            data.model.opacity_logits);
  EXPECT_EQ(quiet.str(), "");

  model.opacity_logits[5] = std::numeric_limits<float>::quiet_NaN();
  ExpectRefused(WriteCase("nan_opacity.ply", InriaBytes(model)),
                "1 NaN/Inf values (first: vertex 5, property opacity)");
  model.opacity_logits[5] = 0;
  model.log_scales[2] = kInf;
  ExpectRefused(WriteCase("inf_scale.ply", InriaBytes(model)),
                "1 NaN/Inf values (first: vertex 0, property scale_2)");
}

TEST(PlyIoErrors, WriterRefusesMismatchedLayoutWithoutTouchingOutput) {
  const std::string path = TempPath("keep.ply");
  WriteAll(path, "previous");
  const GaussianModel model = RandomModel(2, 4, 5);
  EXPECT_THROW(WritePly(path, model, InriaPlyLayout(3, 4)), Error);
  EXPECT_THROW(WritePly(path, model, InriaPlyLayout(2, 5)), Error);
  EXPECT_EQ(ReadAll(path), "previous");
}

TEST(PlyIo, ReadsTightestAsciiWithoutFinalNewline) {
  GaussianModel model;
  model.sh_degree = 0;
  model.Resize(2);
  const std::string inria = InriaBytes(model);
  std::string ascii = Replace(inria.substr(0, inria.find("end_header\n") + 11),
                              "binary_little_endian", "ascii");
  for (int v = 0; v < 2; ++v) {
    for (int p = 0; p < 17; ++p) {
      if (v > 0 || p > 0) ascii += p == 0 ? "\n" : " ";
      ascii += "0";
    }
  }
  const PlyData data = ReadPly(WriteCase("tight.ply", ascii));
  ExpectModelsEqual(data.model, model);
}

}  // namespace
}  // namespace watergs
