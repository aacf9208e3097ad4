// PlayCanvas compressed PLY reading and writing (see compressed_ply_io.h).
#include "gaussian/formats/compressed_ply_io.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "gaussian/formats/codec_util.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

constexpr size_t kMaxHeaderBytes = 1 << 16;

// Chunk properties: 12 required, then 6 optional colour ranges.
constexpr const char* kChunkNames[] = {
    "min_x",       "min_y",       "min_z",       "max_x",       "max_y",
    "max_z",       "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x",
    "max_scale_y", "max_scale_z", "min_r",       "min_g",       "min_b",
    "max_r",       "max_g",       "max_b"};
constexpr int kRequiredChunkProps = 12;
constexpr int kAllChunkProps = 18;
constexpr const char* kVertexNames[] = {"packed_position", "packed_rotation",
                                        "packed_scale", "packed_color"};
// Scale ranges are clamped to this (log-scales of +-Inf occur in files).
constexpr double kScaleRangeLimit = 20.0;

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<std::string> properties;
};

struct Header {
  std::vector<Element> elements;
  size_t bytes = 0;
};

std::vector<std::string> Words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

bool ParseCount(const std::string& s, uint64_t* v) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return !s.empty() && ec == std::errc() && end == s.data() + s.size();
}

// Header lines up to end_header; `size` bounds the search. Returns false if
// there is no end_header within the first kMaxHeaderBytes.
bool HeaderLines(const uint8_t* data, size_t size,
                 std::vector<std::string>* lines, size_t* bytes) {
  const size_t limit = std::min(size, kMaxHeaderBytes);
  size_t start = 0;
  for (size_t i = 0; i < limit; ++i) {
    if (data[i] != '\n') continue;
    std::string line(reinterpret_cast<const char*>(data) + start, i - start);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines->push_back(line);
    start = i + 1;
    if (line == "end_header") {
      *bytes = start;
      return true;
    }
  }
  return false;
}

const char* ExpectedType(const std::string& element) {
  if (element == "chunk") return "float";
  if (element == "vertex") return "uint";
  return "uchar";
}

bool TypeMatches(const std::string& element, const std::string& type) {
  if (element == "chunk") return type == "float" || type == "float32";
  if (element == "vertex") return type == "uint" || type == "uint32";
  return type == "uchar" || type == "uint8";
}

Header ParseHeader(const std::string& name, const uint8_t* data, size_t size) {
  std::vector<std::string> lines;
  Header header;
  if (!HeaderLines(data, size, &lines, &header.bytes)) {
    FailAt(name, "compressed PLY header has no end_header in its first 64 KB");
  }
  if (lines[0] != "ply") FailAt(name, "not a PLY file");
  static const std::vector<std::string> kOrder = {"chunk", "vertex", "sh"};
  bool have_format = false;
  for (size_t l = 1; l + 1 < lines.size(); ++l) {
    const auto words = Words(lines[l]);
    if (words.empty()) FailAt(name, "empty line in compressed PLY header");
    const std::string& key = words[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      if (words.size() != 3 || words[1] != "binary_little_endian") {
        FailAt(name, "compressed PLY must be binary_little_endian, not '" +
                         Printable(lines[l].substr(0, 60)) + "'");
      }
      have_format = true;
    } else if (key == "element") {
      Element e;
      if (words.size() != 3 || !ParseCount(words[2], &e.count)) {
        FailAt(name, "malformed element line '" +
                         Printable(lines[l].substr(0, 60)) + "'");
      }
      e.name = words[1];
      const size_t at = header.elements.size();
      if (at >= kOrder.size() || e.name != kOrder[at]) {
        FailAt(name,
               "compressed PLY elements must be chunk, vertex and "
               "optionally sh, in that order; found '" +
                   Printable(e.name.substr(0, 40)) + "'");
      }
      header.elements.push_back(e);
    } else if (key == "property") {
      if (header.elements.empty()) {
        FailAt(name, "property before any element in compressed PLY header");
      }
      Element& e = header.elements.back();
      if (words.size() != 3 || !TypeMatches(e.name, words[1])) {
        FailAt(name, "property '" + Printable(lines[l].substr(0, 60)) +
                         "' of element " + e.name + " must be " +
                         ExpectedType(e.name));
      }
      if (std::find(e.properties.begin(), e.properties.end(), words[2]) !=
          e.properties.end()) {
        FailAt(name, "property " + Printable(words[2]) + " declared twice");
      }
      e.properties.push_back(words[2]);
    } else {
      FailAt(name, "unknown compressed PLY header line '" +
                       Printable(lines[l].substr(0, 60)) + "'");
    }
  }
  if (!have_format) FailAt(name, "compressed PLY header has no format line");
  if (header.elements.size() < 2) {
    FailAt(name, "compressed PLY needs elements chunk and vertex");
  }
  return header;
}

// Column of each name in `element` (in `names` order); throws if a required
// one is missing or an unknown one is present.
std::vector<int> Columns(const std::string& file, const Element& element,
                         const std::vector<std::string>& names,
                         size_t required) {
  std::vector<int> columns(names.size(), -1);
  for (size_t p = 0; p < element.properties.size(); ++p) {
    const auto it =
        std::find(names.begin(), names.end(), element.properties[p]);
    if (it == names.end()) {
      FailAt(file, "unexpected property " +
                       Printable(element.properties[p].substr(0, 40)) +
                       " in element " + element.name);
    }
    columns[it - names.begin()] = int(p);
  }
  for (size_t k = 0; k < names.size(); ++k) {
    const bool optional_all_absent =
        k >= required && std::all_of(columns.begin() + required, columns.end(),
                                     [](int c) { return c < 0; });
    if (columns[k] < 0 && !optional_all_absent) {
      FailAt(file, "element " + element.name + " lacks property " + names[k]);
    }
  }
  return columns;
}

double UnpackUnorm(uint32_t value, int bits) {
  const uint32_t max = (1u << bits) - 1;
  return double(value & max) / max;
}

double Lerp(double a, double b, double t) { return a * (1 - t) + b * t; }

uint32_t PackUnorm(double v, int bits) {
  const uint32_t max = (1u << bits) - 1;
  return codec::TruncClamp(std::floor(v * max + 0.5), max);
}

// splat-transform's normalisation into a chunk range (0 for a range under
// 1e-5).
double Normalize(double x, double min, double max) {
  if (x <= min) return 0;
  if (x >= max) return 1;
  return max - min < 0.00001 ? 0 : (x - min) / (max - min);
}

uint32_t Pack111011(double x, double y, double z) {
  return PackUnorm(x, 11) << 21 | PackUnorm(y, 10) << 11 | PackUnorm(z, 11);
}

void DecodeRotation(uint32_t v, float* q) {
  const double norm = std::sqrt(2.0);
  const double a = (UnpackUnorm(v >> 20, 10) - 0.5) * norm;
  const double b = (UnpackUnorm(v >> 10, 10) - 0.5) * norm;
  const double c = (UnpackUnorm(v, 10) - 0.5) * norm;
  const double m = std::sqrt(std::max(0.0, 1.0 - (a * a + b * b + c * c)));
  const int largest = int(v >> 30);
  const double rest[3] = {a, b, c};
  for (int k = 0, r = 0; k < 4; ++k) {
    q[k] = float(k == largest ? m : rest[r++]);
  }
}

uint32_t EncodeRotation(const float* quat) {
  auto q = codec::Normalized(quat);
  int largest = 0;
  for (int k = 1; k < 4; ++k) {
    if (std::abs(q[k]) > std::abs(q[largest])) largest = k;
  }
  if (q[largest] < 0) {
    for (double& v : q) v = -v;
  }
  const double norm = std::sqrt(2.0) * 0.5;
  uint32_t result = uint32_t(largest);
  for (int k = 0; k < 4; ++k) {
    if (k != largest) result = result << 10 | PackUnorm(q[k] * norm + 0.5, 10);
  }
  return result;
}

// Spreads the low 10 bits of x to every third bit.
uint32_t Part1By2(uint32_t x) {
  x &= 0x000003ff;
  x = (x ^ (x << 16)) & 0xff0000ff;
  x = (x ^ (x << 8)) & 0x0300f00f;
  x = (x ^ (x << 4)) & 0x030c30c3;
  x = (x ^ (x << 2)) & 0x09249249;
  return x;
}

void SortMorton(const GaussianModel& model, uint32_t* begin, uint32_t* end) {
  const size_t n = size_t(end - begin);
  if (n == 0) return;
  std::array<double, 3> lo, hi;
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (const uint32_t* i = begin; i < end; ++i) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], double(model.means[3 * *i + k]));
      hi[k] = std::max(hi[k], double(model.means[3 * *i + k]));
    }
  }
  std::array<double, 3> mul{};
  bool all_equal = true;
  for (int k = 0; k < 3; ++k) {
    const double len = hi[k] - lo[k];
    if (!std::isfinite(len)) return;
    mul[k] = len == 0 ? 0 : 1024 / len;
    all_equal = all_equal && len == 0;
  }
  if (all_equal) return;
  std::vector<std::pair<uint32_t, uint32_t>> keyed(n);  // (code, index)
  for (size_t j = 0; j < n; ++j) {
    const uint32_t i = begin[j];
    uint32_t cell[3];
    for (int k = 0; k < 3; ++k) {
      cell[k] = uint32_t(
          std::min(1023.0, (double(model.means[3 * i + k]) - lo[k]) * mul[k]));
    }
    keyed[j] = {
        Part1By2(cell[2]) << 2 | Part1By2(cell[1]) << 1 | Part1By2(cell[0]), i};
  }
  std::stable_sort(
      keyed.begin(), keyed.end(),
      [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t j = 0; j < n; ++j) begin[j] = keyed[j].second;
  for (size_t start = 0; start < n;) {
    size_t stop = start + 1;
    while (stop < n && keyed[stop].first == keyed[start].first) ++stop;
    if (stop - start > kCompressedPlyChunk) {
      SortMorton(model, begin + start, begin + stop);
    }
    start = stop;
  }
}

}  // namespace

bool IsCompressedPlyHeader(const uint8_t* data, size_t size) {
  std::vector<std::string> lines;
  size_t bytes = 0;
  HeaderLines(data, size, &lines, &bytes);
  for (const auto& line : lines) {
    const auto words = Words(line);
    if (words.size() >= 2 && words[0] == "element" && words[1] == "chunk") {
      return true;
    }
  }
  return false;
}

GaussianModel DecodeCompressedPly(const std::string& name, const uint8_t* data,
                                  size_t size) {
  const Header header = ParseHeader(name, data, size);
  const Element& chunk = header.elements[0];
  const Element& vertex = header.elements[1];
  const Element* sh =
      header.elements.size() > 2 ? &header.elements[2] : nullptr;
  const std::vector<int> chunk_col = Columns(
      name, chunk,
      std::vector<std::string>(std::begin(kChunkNames), std::end(kChunkNames)),
      kRequiredChunkProps);
  const bool chunk_colors = chunk_col[kRequiredChunkProps] >= 0;
  const std::vector<int> vertex_col =
      Columns(name, vertex,
              std::vector<std::string>(std::begin(kVertexNames),
                                       std::end(kVertexNames)),
              4);
  const uint64_t n = vertex.count;
  int sh_degree = 0;
  std::vector<int> sh_col;
  if (sh != nullptr) {
    const size_t k = sh->properties.size();
    if (k != 9 && k != 24 && k != 45) {
      FailAt(name, "element sh has " + std::to_string(k) +
                       " properties; 3DGS uses 9, 24 or 45");
    }
    std::vector<std::string> names;
    for (size_t j = 0; j < k; ++j)
      names.push_back("f_rest_" + std::to_string(j));
    sh_col = Columns(name, *sh, names, k);
    sh_degree = k == 9 ? 1 : k == 24 ? 2 : 3;
    if (sh->count != n) {
      FailAt(name, "element sh has " + std::to_string(sh->count) +
                       " rows for " + std::to_string(n) + " vertices");
    }
  }
  // Every count is bounded by the file size before any product is formed.
  const uint64_t body = size - header.bytes;
  if (n > body || chunk.count > body) {
    FailAt(name, "header declares " + std::to_string(n) + " vertices and " +
                     std::to_string(chunk.count) + " chunks but the file has " +
                     std::to_string(body) + " bytes of data (truncated?)");
  }
  const uint64_t expected_chunks =
      (n + kCompressedPlyChunk - 1) / kCompressedPlyChunk;
  if (chunk.count != expected_chunks) {
    FailAt(name, std::to_string(chunk.count) + " chunks for " +
                     std::to_string(n) + " vertices (expected " +
                     std::to_string(expected_chunks) + ")");
  }
  const size_t chunk_row = 4 * chunk.properties.size();
  const size_t sh_row = sh ? sh->properties.size() : 0;
  const uint64_t need = chunk.count * chunk_row + n * 16 + n * sh_row;
  if (need != body) {
    FailAt(name,
           need > body
               ? "truncated: the header's counts need " + std::to_string(need) +
                     " bytes of data, the file has " + std::to_string(body)
               : std::to_string(body - need) +
                     " bytes after the data the header declares "
                     "(corrupt file)");
  }
  const uint8_t* chunks = data + header.bytes;
  const uint8_t* vertices = chunks + chunk.count * chunk_row;
  const uint8_t* shs = vertices + n * 16;
  for (uint64_t c = 0; c < chunk.count; ++c) {
    for (size_t p = 0; p < chunk.properties.size(); ++p) {
      if (!std::isfinite(codec::LoadF32(chunks + c * chunk_row + 4 * p))) {
        FailAt(name, "chunk " + std::to_string(c) + " has a NaN/Inf " +
                         Printable(chunk.properties[p]));
      }
    }
  }

  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(size_t(n));
  const int coeffs = NumShCoeffs(sh_degree) - 1;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* crow = chunks + (i / kCompressedPlyChunk) * chunk_row;
    auto range = [&](int k) {
      return double(codec::LoadF32(crow + 4 * chunk_col[k]));
    };
    auto packed = [&](int k) {
      return codec::LoadU32(vertices + 16 * i + 4 * vertex_col[k]);
    };
    const uint32_t pos = packed(0), rot = packed(1), scl = packed(2),
                   col = packed(3);
    const double pt[3] = {UnpackUnorm(pos >> 21, 11),
                          UnpackUnorm(pos >> 11, 10), UnpackUnorm(pos, 11)};
    const double st[3] = {UnpackUnorm(scl >> 21, 11),
                          UnpackUnorm(scl >> 11, 10), UnpackUnorm(scl, 11)};
    const double ct[3] = {UnpackUnorm(col >> 24, 8), UnpackUnorm(col >> 16, 8),
                          UnpackUnorm(col >> 8, 8)};
    for (int k = 0; k < 3; ++k) {
      model.means[3 * i + k] = float(Lerp(range(k), range(3 + k), pt[k]));
      model.log_scales[3 * i + k] =
          float(Lerp(range(6 + k), range(9 + k), st[k]));
      const double rgb =
          chunk_colors ? Lerp(range(12 + k), range(15 + k), ct[k]) : ct[k];
      model.sh_dc[3 * i + k] = float((rgb - 0.5) / codec::kShC0);
    }
    model.opacity_logits[i] = AlphaToOpacityLogit(UnpackUnorm(col, 8));
    DecodeRotation(rot, &model.quats[4 * i]);
    for (int j = 0; j < 3 * coeffs; ++j) {
      const uint8_t v = shs[i * sh_row + sh_col[j]];
      const double t = v == 0 ? 0 : v == 255 ? 1 : (v + 0.5) / 256;
      // f_rest_j is channel-major; the model keeps coefficient-major rgb.
      const int channel = j / coeffs, coeff = j % coeffs;
      model.sh_rest[i * model.sh_rest_stride() + 3 * coeff + channel] =
          float((t - 0.5) * 8);
    }
  }
  // Lerp of finite floats stays finite, except for ranges near FLT_MAX.
  if (model.CountNonFinite() > 0) {
    FailAt(name, "chunk ranges too large for float values");
  }
  return model;
}

std::vector<uint32_t> MortonOrder(const GaussianModel& model) {
  std::vector<uint32_t> order(model.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = uint32_t(i);
  SortMorton(model, order.data(), order.data() + order.size());
  return order;
}

std::string EncodeCompressedPly(const GaussianModel& model,
                                std::vector<uint32_t>* order_out) {
  const size_t bad = model.CountNonFinite();
  if (bad > 0) {
    Fail("compressed PLY: cannot encode a model with " + std::to_string(bad) +
         " NaN/Inf values");
  }
  if (model.size() > std::numeric_limits<uint32_t>::max()) {
    Fail("compressed PLY: more than 2^32 Gaussians");
  }
  const size_t n = model.size();
  const size_t num_chunks = (n + kCompressedPlyChunk - 1) / kCompressedPlyChunk;
  const int coeffs = NumShCoeffs(model.sh_degree) - 1;
  const std::vector<uint32_t> order = MortonOrder(model);

  std::string header =
      "ply\nformat binary_little_endian 1.0\n"
      "comment Generated by watergs\nelement chunk " +
      std::to_string(num_chunks) + "\n";
  for (const char* p : kChunkNames)
    header += std::string("property float ") + p + "\n";
  header += "element vertex " + std::to_string(n) + "\n";
  for (const char* p : kVertexNames)
    header += std::string("property uint ") + p + "\n";
  if (coeffs > 0) {
    header += "element sh " + std::to_string(n) + "\n";
    for (int j = 0; j < 3 * coeffs; ++j) {
      header += "property uchar f_rest_" + std::to_string(j) + "\n";
    }
  }
  header += "end_header\n";

  std::string chunk_bytes, vertex_bytes, sh_bytes;
  chunk_bytes.reserve(num_chunks * kAllChunkProps * 4);
  vertex_bytes.reserve(n * 16);
  sh_bytes.reserve(n * 3 * coeffs);
  for (size_t c = 0; c < num_chunks; ++c) {
    const size_t begin = c * kCompressedPlyChunk;
    const size_t end = std::min(n, begin + kCompressedPlyChunk);
    // Ranges: x y z, log-scales, colours (0.5 + C0 * dc). The last chunk is
    // padded with its last Gaussian, which changes no range.
    std::array<double, 9> lo, hi;
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    auto value = [&](uint32_t i, int k) -> double {
      if (k < 3) return model.means[3 * i + k];
      if (k < 6) return model.log_scales[3 * i + k - 3];
      return model.sh_dc[3 * i + k - 6] * codec::kShC0 + 0.5;
    };
    for (size_t j = begin; j < end; ++j) {
      for (int k = 0; k < 9; ++k) {
        lo[k] = std::min(lo[k], value(order[j], k));
        hi[k] = std::max(hi[k], value(order[j], k));
      }
    }
    for (int k = 3; k < 6; ++k) {
      lo[k] = std::clamp(lo[k], -kScaleRangeLimit, kScaleRangeLimit);
      hi[k] = std::clamp(hi[k], -kScaleRangeLimit, kScaleRangeLimit);
    }
    // Stored as float: normalise against the stored ranges.
    std::array<float, 9> flo, fhi;
    for (int k = 0; k < 9; ++k) {
      flo[k] = float(lo[k]);
      fhi[k] = float(hi[k]);
    }
    for (int g = 0; g < 3; ++g) {  // positions, scales, colours
      for (int k = 0; k < 3; ++k)
        codec::AppendF32(flo[3 * g + k], &chunk_bytes);
      for (int k = 0; k < 3; ++k)
        codec::AppendF32(fhi[3 * g + k], &chunk_bytes);
    }
    for (size_t j = begin; j < end; ++j) {
      const uint32_t i = order[j];
      double t[9];
      for (int k = 0; k < 9; ++k) t[k] = Normalize(value(i, k), flo[k], fhi[k]);
      codec::AppendU32(Pack111011(t[0], t[1], t[2]), &vertex_bytes);
      codec::AppendU32(EncodeRotation(&model.quats[4 * i]), &vertex_bytes);
      codec::AppendU32(Pack111011(t[3], t[4], t[5]), &vertex_bytes);
      const double alpha = OpacityLogitToAlpha(model.opacity_logits[i]);
      codec::AppendU32(PackUnorm(t[6], 8) << 24 | PackUnorm(t[7], 8) << 16 |
                           PackUnorm(t[8], 8) << 8 | PackUnorm(alpha, 8),
                       &vertex_bytes);
      for (int j2 = 0; j2 < 3 * coeffs; ++j2) {
        // f_rest_j2 is channel-major.
        const int channel = j2 / coeffs, coeff = j2 % coeffs;
        const double v =
            model.sh_rest[i * model.sh_rest_stride() + 3 * coeff + channel];
        sh_bytes.push_back(
            char(codec::TruncClamp(std::floor((v / 8 + 0.5) * 256), 255)));
      }
    }
  }
  // The chunk table as splat-transform orders it: min xyz, max xyz, min
  // scale, max scale, min rgb, max rgb (kChunkNames order).
  if (order_out != nullptr) *order_out = order;
  return header + chunk_bytes + vertex_bytes + sh_bytes;
}

void WriteCompressedPly(const std::string& path, const GaussianModel& model) {
  std::string bytes;
  try {
    bytes = EncodeCompressedPly(model);
  } catch (const Error& e) {
    FailAt(path, e.what());
  }
  AtomicWriteFile(path, bytes);
}

}  // namespace watergs
