// PLY reading and writing for 3DGS models. Writes the Inria layout by default
// (binary little-endian, float x y z nx ny nz f_dc_0..2 f_rest_* opacity
// scale_0..2 rot_0..3, f_rest channel-major) and reads files from other 3DGS
// tools (any property order, missing normals, SH degree 0-3, extra or double
// properties, ascii and big-endian). The reader returns a PlyLayout so that a
// model can be written back in exactly the layout it came from: reading and
// writing an unchanged model gives identical bytes (binary files whose model
// properties are float; double model properties are held as float, ascii
// values are rewritten in shortest form, and bytes after the vertex data are
// ignored). Gaussians added or removed after reading keep their extra
// properties only through PlyLayout::RemapExtras (parent's values, or zeros).
#pragma once

#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"

namespace watergs {

// Scalar types of the PLY format.
enum class PlyType {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};

// Data encodings of the PLY format.
enum class PlyFormat { kBinaryLittleEndian, kBinaryBigEndian, kAscii };

struct PlyProperty {
  // Property name, e.g. "f_rest_7".
  std::string name;
  // Scalar type of the stored value.
  PlyType type = PlyType::kFloat32;
  // Type as spelled in the header ("float" or "float32"), kept for round trips.
  std::string type_name = "float";
};

// A `comment` or `obj_info` header line and where it stood.
struct PlyHeaderComment {
  // Full line without line ending, e.g. "comment made by tool X".
  std::string line;
  // Header line it preceded: 0 = format line, 1 = element line, 2 + k =
  // property k, 2 + number of properties = end_header.
  int before = 0;
};

// Everything about a file's format that a GaussianModel does not hold.
// "Extra" properties are those that are not model parameters (normals, and
// anything other tools add); their values are kept per vertex.
struct PlyLayout {
  // Encoding of the vertex data.
  PlyFormat format = PlyFormat::kBinaryLittleEndian;
  // Version token of the format line (always "1.0" in practice).
  std::string format_version = "1.0";
  // Header line ending: "\n" (plyfile >= 0.6, Inria) or "\r\n" (older).
  std::string line_ending = "\n";
  // Comment and obj_info lines of the header.
  std::vector<PlyHeaderComment> comments;
  // Vertex properties in file order.
  std::vector<PlyProperty> properties;
  // Values of the extra properties, N x NumExtras() row-major, as doubles
  // (exact for every PLY scalar type), N = number of Gaussians.
  std::vector<double> extra_values;

  // Indices into `properties` of the extra (non-model) properties.
  std::vector<int> ExtraPropertyIndices() const;
  // Number of extra properties.
  int NumExtras() const {
    return static_cast<int>(ExtraPropertyIndices().size());
  }
  // SH degree implied by the f_rest properties; throws Error if the count is
  // not 0, 9, 24 or 45.
  int ShDegree() const;
  // Makes extra_values follow a model whose Gaussian i came from Gaussian
  // parent[i] of the model this layout was read with; parent[i] < 0 (a new
  // Gaussian with no parent) gets zeros. Use after density control or
  // filtering so that writing keeps each surviving Gaussian's extras.
  void RemapExtras(const std::vector<int64_t>& parent);
  // Extras for n Gaussians all zero (what Inria writes for normals).
  void ZeroExtras(size_t n);
};

// The layout Inria's 3DGS writes for an SH degree (0-3), extras (normals)
// zeroed for n Gaussians.
PlyLayout InriaPlyLayout(int sh_degree, size_t n = 0);

struct PlyReadOptions {
  // Load NaN/Inf model values instead of refusing the file (for inspection).
  // +-Inf opacity logits and -Inf log-scales are never refused: they are
  // replaced whatever this says (see kOpacityLogitLimit).
  bool allow_non_finite = false;
  // Where the one warning line about replaced infinities goes (null: none).
  std::ostream* warnings = &std::cerr;
};

struct PlyData {
  // The Gaussians (sh_degree from the f_rest count).
  GaussianModel model;
  // The file's layout, extras included, to write the model back the same way.
  PlyLayout layout;
  // Number of NaN/Inf values among the model parameters (not counting the
  // replaced ones).
  size_t non_finite_count = 0;
  // Number of +-Inf opacity logits and -Inf log-scales the file held, read
  // as +-kOpacityLogitLimit and kLogScaleFloor (what viewers render).
  size_t replaced_infinities = 0;
  // Size of the file in bytes.
  uint64_t file_size = 0;
  // Bytes of the header, end_header line included.
  uint64_t header_size = 0;
};

// Reads a 3DGS PLY. Throws Error("<path>: <problem>") for anything it cannot
// read: missing file, not a PLY, truncated header or data, vertex count that
// does not fit the file, missing model properties, list properties, other
// elements, an f_rest count other than 0/9/24/45, and (unless allowed) NaN
// and the infinities viewers cannot render (+Inf log-scales, infinite
// positions, rotations or colours). +-Inf opacity logits and -Inf log-scales
// are read as +-20 and -20, with one warning line (count and file).
PlyData ReadPly(const std::string& path, const PlyReadOptions& options = {});

// Writes `model` in the Inria layout (normals zero), atomically.
void WritePly(const std::string& path, const GaussianModel& model);

// Writes `model` in `layout`, atomically. The layout's SH degree must equal the
// model's, and extra_values must hold model.size() rows (see RemapExtras);
// otherwise Error. Model values are converted to each property's type.
void WritePly(const std::string& path, const GaussianModel& model,
              const PlyLayout& layout);

// Name of a PLY scalar type as the spec spells it ("float", "uchar", ...).
const char* PlyTypeName(PlyType type);

}  // namespace watergs
