// PLY reading and writing for 3DGS models (see ply_io.h for the layout).
#include "gaussian/formats/ply_io.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <ostream>
#include <set>
#include <sstream>
#include <type_traits>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

// A header longer than this is not a 3DGS PLY (Inria's is ~1.6 KB).
constexpr size_t kMaxHeaderBytes = 1 << 20;
// Vertices decoded per block when streaming binary data.
constexpr size_t kRowsPerBlock = 1 << 14;

// Which model array a property feeds; kExtra = kept in the layout.
enum class Field { kExtra, kMean, kLogScale, kQuat, kOpacity, kShDc, kShRest };

// Where one property's value lives in the model.
struct Role {
  // Model array (or extra).
  Field field = Field::kExtra;
  // Offset within the Gaussian's row of that array (extra column if kExtra).
  int offset = 0;
};

struct TypeInfo {
  const char* name;
  const char* alt_name;
  PlyType type;
  int size;
};

constexpr TypeInfo kTypes[] = {
    {"char", "int8", PlyType::kInt8, 1},
    {"uchar", "uint8", PlyType::kUint8, 1},
    {"short", "int16", PlyType::kInt16, 2},
    {"ushort", "uint16", PlyType::kUint16, 2},
    {"int", "int32", PlyType::kInt32, 4},
    {"uint", "uint32", PlyType::kUint32, 4},
    {"float", "float32", PlyType::kFloat32, 4},
    {"double", "float64", PlyType::kFloat64, 8},
};

int TypeSize(PlyType type) {
  for (const auto& t : kTypes) {
    if (t.type == type) return t.size;
  }
  return 0;
}

bool ParseTypeName(const std::string& name, PlyType* type) {
  for (const auto& t : kTypes) {
    if (name == t.name || name == t.alt_name) {
      *type = t.type;
      return true;
    }
  }
  return false;
}

// Parses a non-negative decimal integer that spans the whole string.
bool ParseUint(const std::string& s, uint64_t* value) {
  if (s.empty()) return false;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *value);
  return ec == std::errc() && end == s.data() + s.size();
}

// Number of f_rest_* properties.
int CountRest(const std::vector<PlyProperty>& properties) {
  int n = 0;
  for (const auto& p : properties) n += p.name.rfind("f_rest_", 0) == 0 ? 1 : 0;
  return n;
}

int ShDegreeForRestCount(int num_rest) {
  for (int degree = 0; degree <= 3; ++degree) {
    if (num_rest == 3 * (NumShCoeffs(degree) - 1)) return degree;
  }
  return -1;
}

// Role of a property name; num_rest = f_rest count of the file. Returns false
// for an f_rest_j with j out of range.
bool ClassifyProperty(const std::string& name, int num_rest, Role* role) {
  static const std::pair<const char*, Role> kFixed[] = {
      {"x", {Field::kMean, 0}},           {"y", {Field::kMean, 1}},
      {"z", {Field::kMean, 2}},           {"scale_0", {Field::kLogScale, 0}},
      {"scale_1", {Field::kLogScale, 1}}, {"scale_2", {Field::kLogScale, 2}},
      {"rot_0", {Field::kQuat, 0}},       {"rot_1", {Field::kQuat, 1}},
      {"rot_2", {Field::kQuat, 2}},       {"rot_3", {Field::kQuat, 3}},
      {"opacity", {Field::kOpacity, 0}},  {"f_dc_0", {Field::kShDc, 0}},
      {"f_dc_1", {Field::kShDc, 1}},      {"f_dc_2", {Field::kShDc, 2}},
  };
  for (const auto& [fixed_name, fixed_role] : kFixed) {
    if (name == fixed_name) {
      *role = fixed_role;
      return true;
    }
  }
  if (name.rfind("f_rest_", 0) == 0) {
    uint64_t j = 0;
    if (!ParseUint(name.substr(7), &j) || j >= static_cast<uint64_t>(num_rest))
      return false;
    // File order is channel-major (all R, then G, then B); the model keeps
    // coefficient-major rgb-interleaved.
    const int coeffs = num_rest / 3;
    const int channel = static_cast<int>(j) / coeffs;
    const int coeff = static_cast<int>(j) % coeffs;
    *role = {Field::kShRest, coeff * 3 + channel};
    return true;
  }
  *role = {Field::kExtra, 0};
  return true;
}

// `text` with every byte outside printable ASCII written as \xNN: errors
// quote header text, which in a damaged or non-PLY file may be binary (NUL
// included), and a PLY header is ASCII.
std::string Ascii(const std::string& text) {
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte >= 0x7f) {
      out += std::string("\\x") + kHex[byte >> 4] + kHex[byte & 15];
    } else {
      out += c;
    }
  }
  return out;
}

// Roles of all properties (extras numbered in file order). Throws Error at
// `path` if a model property is missing, mistyped or out of range.
std::vector<Role> ResolveRoles(const std::string& path,
                               const std::vector<PlyProperty>& properties) {
  const int num_rest = CountRest(properties);
  if (ShDegreeForRestCount(num_rest) < 0) {
    FailAt(path,
           std::to_string(num_rest) +
               " f_rest properties; 3DGS uses 0, 9, 24 or 45 (SH degree 0-3)");
  }
  std::vector<Role> roles(properties.size());
  int extras = 0;
  int model_properties = 0;
  std::set<std::pair<Field, int>> filled;
  for (size_t p = 0; p < properties.size(); ++p) {
    const auto& prop = properties[p];
    if (!ClassifyProperty(prop.name, num_rest, &roles[p])) {
      FailAt(path, "property " + Ascii(prop.name) + " is out of range for " +
                       std::to_string(num_rest) +
                       " f_rest properties (expected f_rest_0..f_rest_" +
                       std::to_string(num_rest - 1) + ")");
    }
    if (roles[p].field == Field::kExtra) {
      roles[p].offset = extras++;
      continue;
    }
    ++model_properties;
    if (!filled.insert({roles[p].field, roles[p].offset}).second) {
      FailAt(path, "property " + Ascii(prop.name) +
                       " duplicates another property's parameter");
    }
    if (prop.type != PlyType::kFloat32 && prop.type != PlyType::kFloat64) {
      FailAt(path, "property " + Ascii(prop.name) + " has type " +
                       Ascii(prop.type_name) +
                       "; 3DGS parameters must be float or double");
    }
  }
  if (model_properties != 14 + num_rest) {
    for (const char* name :
         {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0",
          "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) {
      const bool found =
          std::any_of(properties.begin(), properties.end(),
                      [&](const PlyProperty& p) { return p.name == name; });
      if (!found) {
        const bool has_rgb =
            std::any_of(properties.begin(), properties.end(),
                        [](const PlyProperty& p) { return p.name == "red"; });
        FailAt(
            path,
            std::string("missing vertex property ") + name +
                (has_rgb ? " (this looks like a coloured point cloud, not 3DGS)"
                         : ""));
      }
    }
  }
  return roles;
}

// Model array, stride and property offset for a role; Array is
// std::vector<float> when reading, const std::vector<float> when writing.
template <typename Array>
struct Slot {
  Array* array = nullptr;
  int stride = 0;
  int offset = 0;
};

template <typename Model>
auto SlotFor(Model& model, const Role& role)
    -> Slot<std::remove_reference_t<decltype((model.means))>> {
  switch (role.field) {
    case Field::kMean:
      return {&model.means, 3, role.offset};
    case Field::kLogScale:
      return {&model.log_scales, 3, role.offset};
    case Field::kQuat:
      return {&model.quats, 4, role.offset};
    case Field::kOpacity:
      return {&model.opacity_logits, 1, role.offset};
    case Field::kShDc:
      return {&model.sh_dc, 3, role.offset};
    case Field::kShRest:
      return {&model.sh_rest, model.sh_rest_stride(), role.offset};
    case Field::kExtra:
      break;
  }
  return {};
}

// Unsigned integer of the same size as T.
template <typename T>
using BitsOf = std::conditional_t<
    sizeof(T) == 1, uint8_t,
    std::conditional_t<sizeof(T) == 2, uint16_t,
                       std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;

// std::byteswap is C++23.
template <typename U>
U ByteSwap(U bits) {
  if constexpr (sizeof(U) == 1) return bits;
  if constexpr (sizeof(U) == 2) return __builtin_bswap16(bits);
  if constexpr (sizeof(U) == 4) return __builtin_bswap32(bits);
  if constexpr (sizeof(U) == 8) return __builtin_bswap64(bits);
}

template <typename T>
T LoadScalar(const char* src, bool swap) {
  BitsOf<T> bits;
  std::memcpy(&bits, src, sizeof(bits));
  if (swap) bits = ByteSwap(bits);
  return std::bit_cast<T>(bits);
}

double LoadValue(PlyType type, const char* src, bool swap) {
  switch (type) {
    case PlyType::kInt8:
      return LoadScalar<int8_t>(src, swap);
    case PlyType::kUint8:
      return LoadScalar<uint8_t>(src, swap);
    case PlyType::kInt16:
      return LoadScalar<int16_t>(src, swap);
    case PlyType::kUint16:
      return LoadScalar<uint16_t>(src, swap);
    case PlyType::kInt32:
      return LoadScalar<int32_t>(src, swap);
    case PlyType::kUint32:
      return LoadScalar<uint32_t>(src, swap);
    case PlyType::kFloat32:
      return LoadScalar<float>(src, swap);
    case PlyType::kFloat64:
      return LoadScalar<double>(src, swap);
  }
  return 0;
}

template <typename T>
void StoreScalar(T value, bool swap, char* dst) {
  BitsOf<T> bits = std::bit_cast<BitsOf<T>>(value);
  if (swap) bits = ByteSwap(bits);
  std::memcpy(dst, &bits, sizeof(bits));
}

// Integer conversion that saturates instead of invoking undefined behaviour.
template <typename T>
T ToInteger(double v) {
  if (!(v == v)) return 0;
  const double lo = static_cast<double>(std::numeric_limits<T>::min());
  const double hi = static_cast<double>(std::numeric_limits<T>::max());
  return static_cast<T>(std::nearbyint(std::clamp(v, lo, hi)));
}

void StoreValue(PlyType type, double v, bool swap, char* dst) {
  switch (type) {
    case PlyType::kInt8:
      return StoreScalar(ToInteger<int8_t>(v), swap, dst);
    case PlyType::kUint8:
      return StoreScalar(ToInteger<uint8_t>(v), swap, dst);
    case PlyType::kInt16:
      return StoreScalar(ToInteger<int16_t>(v), swap, dst);
    case PlyType::kUint16:
      return StoreScalar(ToInteger<uint16_t>(v), swap, dst);
    case PlyType::kInt32:
      return StoreScalar(ToInteger<int32_t>(v), swap, dst);
    case PlyType::kUint32:
      return StoreScalar(ToInteger<uint32_t>(v), swap, dst);
    case PlyType::kFloat32:
      return StoreScalar(static_cast<float>(v), swap, dst);
    case PlyType::kFloat64:
      return StoreScalar(v, swap, dst);
  }
}

// ---------------------------------------------------------------- header ---

struct ParsedHeader {
  PlyLayout layout;
  uint64_t vertex_count = 0;
  uint64_t header_size = 0;
};

std::vector<std::string> SplitWords(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

// Reads one header line (without its ending) into `line`; false at EOF.
bool ReadHeaderLine(std::istream& in, std::string* line, uint64_t* consumed,
                    bool* crlf) {
  if (!std::getline(in, *line)) return false;
  *consumed += line->size() + (in.eof() ? 0 : 1);
  *crlf = !line->empty() && line->back() == '\r';
  if (*crlf) line->pop_back();
  return !in.eof();  // a header line with no newline means the file ended
}

void ParseFormatLine(const std::string& path,
                     const std::vector<std::string>& words, PlyLayout* layout) {
  if (words.size() != 3) FailAt(path, "malformed format line in PLY header");
  if (words[1] == "binary_little_endian") {
    layout->format = PlyFormat::kBinaryLittleEndian;
  } else if (words[1] == "binary_big_endian") {
    layout->format = PlyFormat::kBinaryBigEndian;
  } else if (words[1] == "ascii") {
    layout->format = PlyFormat::kAscii;
  } else {
    FailAt(path, "unknown PLY format '" + Ascii(words[1]) + "'");
  }
  layout->format_version = words[2];
}

void ParsePropertyLine(const std::string& path,
                       const std::vector<std::string>& words,
                       PlyLayout* layout) {
  if (words.size() >= 2 && words[1] == "list") {
    FailAt(
        path,
        "list property '" + Ascii(words.back()) +
            "' in element vertex is not supported (3DGS vertices are scalars)");
  }
  if (words.size() != 3) FailAt(path, "malformed property line in PLY header");
  PlyProperty prop;
  if (!ParseTypeName(words[1], &prop.type)) {
    FailAt(path, "unknown type '" + Ascii(words[1]) + "' of property " +
                     Ascii(words[2]));
  }
  prop.type_name = words[1];
  prop.name = words[2];
  for (const auto& other : layout->properties) {
    if (other.name == prop.name)
      FailAt(path, "property " + Ascii(prop.name) + " declared twice");
  }
  layout->properties.push_back(prop);
}

ParsedHeader ParseHeader(const std::string& path, std::istream& in) {
  ParsedHeader header;
  PlyLayout& layout = header.layout;
  std::string line;
  bool crlf = false;
  if (!ReadHeaderLine(in, &line, &header.header_size, &crlf) || line != "ply") {
    FailAt(path, "not a PLY file (does not start with 'ply')");
  }
  layout.line_ending = crlf ? "\r\n" : "\n";
  bool have_format = false;
  bool have_vertex = false;
  int structural = 0;  // header lines seen, counted as in PlyHeaderComment
  while (true) {
    if (header.header_size > kMaxHeaderBytes) {
      FailAt(path, "PLY header longer than 1 MB without end_header");
    }
    if (!ReadHeaderLine(in, &line, &header.header_size, &crlf)) {
      FailAt(path, "truncated PLY header (no end_header)");
    }
    const auto words = SplitWords(line);
    if (words.empty()) FailAt(path, "empty line in PLY header");
    const std::string& key = words[0];
    if (key == "comment" || key == "obj_info") {
      layout.comments.push_back({line, structural});
    } else if (key == "format") {
      if (have_format || structural != 0)
        FailAt(path, "misplaced format line in PLY header");
      ParseFormatLine(path, words, &layout);
      have_format = true;
      structural = 1;
    } else if (key == "element") {
      if (!have_format)
        FailAt(path, "PLY header has no format line before its elements");
      if (words.size() != 3)
        FailAt(path, "malformed element line in PLY header");
      if (words[1] != "vertex" || have_vertex) {
        FailAt(path,
               "element '" + Ascii(words[1]) +
                   "' is not supported (a 3DGS PLY has one 'vertex' element)");
      }
      if (!ParseUint(words[2], &header.vertex_count)) {
        FailAt(path, "bad vertex count '" + Ascii(words[2]) + "'");
      }
      have_vertex = true;
      structural = 2;
    } else if (key == "property") {
      if (!have_vertex)
        FailAt(path, "property before any element in PLY header");
      ParsePropertyLine(path, words, &layout);
      ++structural;
    } else if (key == "end_header") {
      break;
    } else {
      const bool binary = std::any_of(line.begin(), line.end(), [](char c) {
        return static_cast<unsigned char>(c) < 0x20 ||
               static_cast<unsigned char>(c) >= 0x7f;
      });
      FailAt(path,
             (binary ? "binary bytes in the PLY header '"
                     : "unknown PLY header line '") +
                 Ascii(line.substr(0, 60)) + "'" +
                 (binary ? " (no end_header before the vertex data?)" : ""));
    }
  }
  if (!have_vertex) FailAt(path, "PLY header declares no vertex element");
  return header;
}

// ------------------------------------------------------------------ data ---

// Decodes property values into the model or the extras; tracks NaN/Inf.
class VertexSink {
 public:
  VertexSink(GaussianModel& model, PlyLayout& layout,
             const std::vector<Role>& roles)
      : layout_(layout), num_extras_(layout.NumExtras()) {
    for (const auto& role : roles) slots_.push_back(SlotFor(model, role));
    roles_ = roles;
  }

  void Put(size_t vertex, size_t property, double value) {
    const auto& s = slots_[property];
    if (s.array == nullptr) {
      layout_.extra_values[vertex * num_extras_ + roles_[property].offset] =
          value;
      return;
    }
    float f = static_cast<float>(value);
    if (std::isinf(f)) {
      // What a quantised file legitimately decodes to: alpha 0 or 1, scale 0.
      const Field field = roles_[property].field;
      if (field == Field::kOpacity) {
        f = f > 0 ? kOpacityLogitLimit : -kOpacityLogitLimit;
        ++replaced_;
      } else if (field == Field::kLogScale && f < 0) {
        f = kLogScaleFloor;
        ++replaced_;
      }
    }
    (*s.array)[vertex * s.stride + s.offset] = f;
    if (!std::isfinite(f)) {
      if (non_finite_ == 0) first_bad_ = {vertex, property};
      ++non_finite_;
    }
  }

  size_t non_finite() const { return non_finite_; }
  size_t replaced() const { return replaced_; }
  std::pair<size_t, size_t> first_bad() const { return first_bad_; }

 private:
  PlyLayout& layout_;
  int num_extras_;
  std::vector<Slot<std::vector<float>>> slots_;
  std::vector<Role> roles_;
  size_t non_finite_ = 0;
  size_t replaced_ = 0;
  std::pair<size_t, size_t> first_bad_;
};

void ReadBinaryData(const std::string& path, std::istream& in, uint64_t n,
                    const PlyLayout& layout, VertexSink& sink) {
  const bool swap = (layout.format == PlyFormat::kBinaryBigEndian) ==
                    (std::endian::native == std::endian::little);
  std::vector<int> sizes;
  size_t row = 0;
  for (const auto& p : layout.properties) {
    sizes.push_back(TypeSize(p.type));
    row += sizes.back();
  }
  std::vector<char> block;
  for (uint64_t start = 0; start < n; start += kRowsPerBlock) {
    const size_t rows =
        static_cast<size_t>(std::min<uint64_t>(kRowsPerBlock, n - start));
    block.resize(rows * row);
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    if (static_cast<size_t>(in.gcount()) != block.size()) {
      FailAt(path, "truncated vertex data (file ends inside vertex " +
                       std::to_string(start + in.gcount() / row) + " of " +
                       std::to_string(n) + ")");
    }
    const char* src = block.data();
    for (size_t r = 0; r < rows; ++r) {
      for (size_t p = 0; p < sizes.size(); ++p) {
        sink.Put(start + r, p, LoadValue(layout.properties[p].type, src, swap));
        src += sizes[p];
      }
    }
  }
}

void ReadAsciiData(const std::string& path, std::istream& in, uint64_t n,
                   const PlyLayout& layout, VertexSink& sink) {
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  const char* cur = text.data();
  const char* end = text.data() + text.size();
  const size_t num_props = layout.properties.size();
  for (uint64_t v = 0; v < n; ++v) {
    for (size_t p = 0; p < num_props; ++p) {
      while (cur < end && std::isspace(static_cast<unsigned char>(*cur))) ++cur;
      if (cur == end) {
        FailAt(path, "truncated vertex data (ascii file ends at vertex " +
                         std::to_string(v) + " of " + std::to_string(n) + ")");
      }
      double value = 0;
      auto [next, ec] = std::from_chars(cur, end, value);
      if (ec == std::errc::result_out_of_range) {
        value = std::numeric_limits<double>::infinity();
      } else if (ec != std::errc()) {
        FailAt(path, "bad ascii value at vertex " + std::to_string(v) +
                         ", property " + Ascii(layout.properties[p].name));
      }
      sink.Put(v, p, value);
      cur = next;
    }
  }
}

// Refuses a vertex count the remaining bytes cannot hold, before allocating.
void CheckVertexCount(const std::string& path, uint64_t n, uint64_t data_bytes,
                      const PlyLayout& layout) {
  uint64_t row = 0;
  for (const auto& p : layout.properties) row += TypeSize(p.type);
  // An ascii value takes at least one digit and one separator.
  const uint64_t min_row =
      layout.format == PlyFormat::kAscii ? 2 * layout.properties.size() : row;
  // (+1: the last ascii value needs no separator.)
  const uint64_t slack = layout.format == PlyFormat::kAscii ? 1 : 0;
  if (min_row == 0 || n > (data_bytes + slack) / min_row) {
    FailAt(path, "header declares " + std::to_string(n) +
                     " vertices but the file has only " +
                     std::to_string(data_bytes) +
                     " bytes of vertex data (truncated or corrupt)");
  }
  // Binary data must end with the last vertex: extra bytes mean the count
  // disagrees with the data.
  if (layout.format != PlyFormat::kAscii && n * row < data_bytes) {
    FailAt(path, std::to_string(data_bytes - n * row) +
                     " bytes after the last of the " + std::to_string(n) +
                     " vertices the header declares (corrupt file)");
  }
}

// ---------------------------------------------------------------- writer ---

void CheckModelShape(const std::string& path, const GaussianModel& m) {
  const size_t n = m.size();
  if (m.means.size() != 3 * n || m.log_scales.size() != 3 * n ||
      m.quats.size() != 4 * n || m.sh_dc.size() != 3 * n ||
      m.sh_rest.size() != n * m.sh_rest_stride()) {
    FailAt(path, "cannot write: model arrays have inconsistent sizes");
  }
}

std::string HeaderText(const PlyLayout& layout, size_t n) {
  std::string out = "ply" + layout.line_ending;
  auto comments_before = [&](int index) {
    for (const auto& c : layout.comments) {
      if (c.before == index) out += c.line + layout.line_ending;
    }
  };
  static const char* kFormatNames[] = {"binary_little_endian",
                                       "binary_big_endian", "ascii"};
  comments_before(0);
  out += std::string("format ") +
         kFormatNames[static_cast<int>(layout.format)] + " " +
         layout.format_version + layout.line_ending;
  comments_before(1);
  out += "element vertex " + std::to_string(n) + layout.line_ending;
  for (size_t p = 0; p < layout.properties.size(); ++p) {
    comments_before(2 + static_cast<int>(p));
    out += "property " + layout.properties[p].type_name + " " +
           layout.properties[p].name + layout.line_ending;
  }
  comments_before(2 + static_cast<int>(layout.properties.size()));
  return out + "end_header" + layout.line_ending;
}

// Value of property p of Gaussian i.
struct ValueSource {
  std::vector<Slot<const std::vector<float>>> slots;
  std::vector<int> extra_column;
  const std::vector<double>* extras;
  int num_extras;

  double Get(size_t i, size_t p) const {
    const auto& s = slots[p];
    if (s.array == nullptr) return (*extras)[i * num_extras + extra_column[p]];
    return (*s.array)[i * s.stride + s.offset];
  }
};

void AppendAsciiValue(PlyType type, double v, std::string* out) {
  char buf[64];
  std::to_chars_result r;
  if (type == PlyType::kFloat32) {
    r = std::to_chars(buf, buf + sizeof(buf), static_cast<float>(v));
  } else if (type == PlyType::kFloat64) {
    r = std::to_chars(buf, buf + sizeof(buf), v);
  } else {
    r = std::to_chars(buf, buf + sizeof(buf), ToInteger<int64_t>(v));
  }
  out->append(buf, r.ptr);
}

void WriteData(std::ostream& out, const PlyLayout& layout,
               const ValueSource& src, size_t n) {
  const size_t num_props = layout.properties.size();
  std::string block;
  if (layout.format == PlyFormat::kAscii) {
    for (size_t i = 0; i < n; ++i) {
      for (size_t p = 0; p < num_props; ++p) {
        if (p > 0) block += ' ';
        AppendAsciiValue(layout.properties[p].type, src.Get(i, p), &block);
      }
      block += layout.line_ending;
      if (block.size() > (1 << 20)) out << block, block.clear();
    }
    out << block;
    return;
  }
  const bool swap = (layout.format == PlyFormat::kBinaryBigEndian) ==
                    (std::endian::native == std::endian::little);
  size_t row = 0;
  for (const auto& p : layout.properties) row += TypeSize(p.type);
  for (size_t start = 0; start < n; start += kRowsPerBlock) {
    const size_t rows = std::min(kRowsPerBlock, n - start);
    block.resize(rows * row);
    char* dst = block.data();
    for (size_t i = start; i < start + rows; ++i) {
      for (size_t p = 0; p < num_props; ++p) {
        StoreValue(layout.properties[p].type, src.Get(i, p), swap, dst);
        dst += TypeSize(layout.properties[p].type);
      }
    }
    out.write(block.data(), static_cast<std::streamsize>(block.size()));
  }
}

}  // namespace

const char* PlyTypeName(PlyType type) {
  for (const auto& t : kTypes) {
    if (t.type == type) return t.name;
  }
  return "?";
}

std::vector<int> PlyLayout::ExtraPropertyIndices() const {
  const int num_rest = CountRest(properties);
  std::vector<int> extras;
  for (size_t p = 0; p < properties.size(); ++p) {
    Role role;
    if (ClassifyProperty(properties[p].name, num_rest, &role) &&
        role.field == Field::kExtra) {
      extras.push_back(static_cast<int>(p));
    }
  }
  return extras;
}

int PlyLayout::ShDegree() const {
  const int num_rest = CountRest(properties);
  const int degree = ShDegreeForRestCount(num_rest);
  if (degree < 0) {
    Fail("PLY layout has " + std::to_string(num_rest) +
         " f_rest properties (not 0, 9, 24, 45)");
  }
  return degree;
}

void PlyLayout::RemapExtras(const std::vector<int64_t>& parent) {
  const size_t e = static_cast<size_t>(NumExtras());
  const size_t old_rows = e == 0 ? 0 : extra_values.size() / e;
  std::vector<double> remapped(parent.size() * e, 0.0);
  for (size_t i = 0; i < parent.size(); ++i) {
    if (parent[i] < 0) continue;
    if (static_cast<size_t>(parent[i]) >= old_rows && e > 0) {
      Fail("PlyLayout::RemapExtras: parent " + std::to_string(parent[i]) +
           " out of range (" + std::to_string(old_rows) + " Gaussians)");
    }
    std::copy_n(extra_values.begin() + parent[i] * e, e,
                remapped.begin() + i * e);
  }
  extra_values = std::move(remapped);
}

void PlyLayout::ZeroExtras(size_t n) {
  extra_values.assign(n * NumExtras(), 0.0);
}

PlyLayout InriaPlyLayout(int sh_degree, size_t n) {
  PlyLayout layout;
  auto add = [&](const std::string& name) {
    layout.properties.push_back({name});
  };
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz"}) add(name);
  for (int i = 0; i < 3; ++i) add("f_dc_" + std::to_string(i));
  for (int i = 0; i < 3 * (NumShCoeffs(sh_degree) - 1); ++i)
    add("f_rest_" + std::to_string(i));
  add("opacity");
  for (int i = 0; i < 3; ++i) add("scale_" + std::to_string(i));
  for (int i = 0; i < 4; ++i) add("rot_" + std::to_string(i));
  layout.ZeroExtras(n);
  return layout;
}

PlyData ReadPly(const std::string& path, const PlyReadOptions& options) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) FailAt(path, "file not found");
  if (std::filesystem::is_directory(path, ec))
    FailAt(path, "is a directory, expected a PLY file");
  PlyData data;
  data.file_size = std::filesystem::file_size(path, ec);
  if (ec) FailAt(path, "cannot read file size: " + ec.message());
  std::ifstream in(path, std::ios::binary);
  if (!in) FailAt(path, std::string("cannot open: ") + std::strerror(errno));

  ParsedHeader header = ParseHeader(path, in);
  const std::vector<Role> roles = ResolveRoles(path, header.layout.properties);
  data.layout = std::move(header.layout);
  data.header_size = header.header_size;
  CheckVertexCount(path, header.vertex_count, data.file_size - data.header_size,
                   data.layout);

  const size_t n = static_cast<size_t>(header.vertex_count);
  data.model.sh_degree = data.layout.ShDegree();
  data.model.Resize(n);
  data.layout.ZeroExtras(n);
  VertexSink sink(data.model, data.layout, roles);
  if (data.layout.format == PlyFormat::kAscii) {
    ReadAsciiData(path, in, n, data.layout, sink);
  } else {
    ReadBinaryData(path, in, n, data.layout, sink);
  }
  data.non_finite_count = sink.non_finite();
  data.replaced_infinities = sink.replaced();
  if (data.non_finite_count > 0 && !options.allow_non_finite) {
    const auto [vertex, property] = sink.first_bad();
    FailAt(path, std::to_string(data.non_finite_count) +
                     " NaN/Inf values (first: vertex " +
                     std::to_string(vertex) + ", property " +
                     Ascii(data.layout.properties[property].name) + ")");
  }
  WarnInfinitiesReplaced(path, data.replaced_infinities, options.warnings);
  return data;
}

void WritePly(const std::string& path, const GaussianModel& model) {
  WritePly(path, model, InriaPlyLayout(model.sh_degree, model.size()));
}

void WritePly(const std::string& path, const GaussianModel& model,
              const PlyLayout& layout) {
  CheckModelShape(path, model);
  const std::vector<Role> roles = ResolveRoles(path, layout.properties);
  if (layout.ShDegree() != model.sh_degree) {
    FailAt(path, "cannot write: layout has SH degree " +
                     std::to_string(layout.ShDegree()) + ", model has " +
                     std::to_string(model.sh_degree));
  }
  const int num_extras = layout.NumExtras();
  if (layout.extra_values.size() != model.size() * num_extras) {
    FailAt(path,
           "cannot write: layout holds extra properties for " +
               std::to_string(
                   num_extras ? layout.extra_values.size() / num_extras : 0) +
               " Gaussians, model has " + std::to_string(model.size()) +
               " (call PlyLayout::RemapExtras)");
  }
  ValueSource src;
  src.extras = &layout.extra_values;
  src.num_extras = num_extras;
  for (const Role& role : roles) {
    src.slots.push_back(SlotFor(model, role));
    src.extra_column.push_back(role.field == Field::kExtra ? role.offset : -1);
  }
  AtomicWriteFile(path, [&](std::ostream& out) {
    out << HeaderText(layout, model.size());
    WriteData(out, layout, src, model.size());
  });
}

}  // namespace watergs
