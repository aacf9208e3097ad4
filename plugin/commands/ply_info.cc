// `watergs ply_info`: summary of a 3DGS model file (count, SH degree, layout,
// attribute ranges in their activated units, NaN/Inf count, bytes per
// Gaussian). Reads every format the model loader does (PLY, compressed PLY,
// .spz, .splat, SOG); the layout lines are a PLY's only.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "gaussian/formats/model_io.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"

namespace {

// Running min/max/mean of activated values whose file value is finite;
// counts the file values that are NaN/Inf, so that the column of counts
// sums to the file's total (an activation may overflow a finite value: exp
// of a log-scale of 800 is shown as inf in the range, not counted).
struct RangeStats {
  double min = std::numeric_limits<double>::infinity();
  double max = -std::numeric_limits<double>::infinity();
  double sum = 0;
  size_t finite = 0;
  size_t non_finite = 0;

  void Add(float raw, double activated) {
    if (!std::isfinite(raw)) {
      ++non_finite;
      return;
    }
    min = std::min(min, activated);
    max = std::max(max, activated);
    sum += activated;
    ++finite;
  }
};

// Stats of column `offset` of an N x stride array after `activation`.
template <typename F>
RangeStats Column(const std::vector<float>& values, int stride, int offset,
                  F&& activation) {
  RangeStats s;
  for (size_t i = offset; i < values.size(); i += stride) {
    s.Add(values[i], activation(values[i]));
  }
  return s;
}

// Values of a trained model stay far below this in magnitude (positions in
// scene units, log-scales, logits, SH coefficients, quaternions); the
// floats of a file read with the wrong byte order mostly do not.
constexpr double kImplausible = 1e6;

// How many of the model's values are NaN/Inf or beyond kImplausible, of
// how many.
std::pair<size_t, size_t> CountImplausible(const watergs::GaussianModel& m) {
  size_t bad = 0, total = 0;
  for (const std::vector<float>* values :
       {&m.means, &m.log_scales, &m.opacity_logits, &m.sh_dc, &m.sh_rest,
        &m.quats}) {
    for (const float v : *values) {
      bad += !(std::abs(v) <= kImplausible);
    }
    total += values->size();
  }
  return {bad, total};
}

void PrintRow(const std::string& name, const RangeStats& s) {
  char line[160];
  if (s.finite == 0) {
    std::snprintf(line, sizeof(line), "  %-20s %14s %14s %14s %10zu\n",
                  name.c_str(), "-", "-", "-", s.non_finite);
  } else {
    std::snprintf(line, sizeof(line), "  %-20s %14.6g %14.6g %14.6g %10zu\n",
                  name.c_str(), s.min, s.max, s.sum / s.finite, s.non_finite);
  }
  std::fputs(line, stdout);
}

// Splits "f_rest_12" into ("f_rest_", 12); number -1 if there is none.
std::pair<std::string, long> SplitNumber(const std::string& name) {
  size_t digits = name.size();
  while (digits > 0 &&
         std::isdigit(static_cast<unsigned char>(name[digits - 1]))) {
    --digits;
  }
  if (digits == name.size() || name.size() - digits > 9) return {name, -1};
  return {name.substr(0, digits), std::stol(name.substr(digits))};
}

// "x y z nx ny nz f_dc_0..2 f_rest_0..44 ..." with types where not float.
std::string DescribeProperties(const std::vector<watergs::PlyProperty>& props) {
  std::string out;
  for (size_t p = 0; p < props.size();) {
    const auto [prefix, first] = SplitNumber(props[p].name);
    size_t q = p + 1;
    while (first >= 0 && q < props.size() && props[q].type == props[p].type &&
           SplitNumber(props[q].name) ==
               std::make_pair(prefix, first + static_cast<long>(q - p))) {
      ++q;
    }
    if (!out.empty()) out += ' ';
    out += props[p].name;
    if (q - p > 1) out += ".." + std::to_string(first + (q - p - 1));
    if (props[p].type != watergs::PlyType::kFloat32) {
      out += std::string(":") + props[p].type_name;
    }
    p = q;
  }
  return out;
}

const char* FormatName(watergs::PlyFormat format) {
  switch (format) {
    case watergs::PlyFormat::kBinaryLittleEndian:
      return "binary_little_endian";
    case watergs::PlyFormat::kBinaryBigEndian:
      return "binary_big_endian";
    case watergs::PlyFormat::kAscii:
      return "ascii";
  }
  return "?";
}

void PrintRanges(const watergs::GaussianModel& m) {
  const auto identity = [](float v) { return double(v); };
  const auto exp = [](float v) { return std::exp(double(v)); };
  const auto sigmoid = [](float v) {
    return 1.0 / (1.0 + std::exp(-double(v)));
  };
  const auto colour = [](float v) { return double(watergs::ShDcToRgb(v)); };
  std::printf(
      "Attribute ranges (finite values):\n  %-20s %14s %14s %14s %10s\n",
      "attribute", "min", "max", "mean", "NaN/Inf");
  const char* axes[] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k)
    PrintRow(axes[k], Column(m.means, 3, k, identity));
  for (int k = 0; k < 3; ++k) {
    PrintRow("scale_" + std::to_string(k) + " (exp)",
             Column(m.log_scales, 3, k, exp));
  }
  PrintRow("opacity (sigmoid)", Column(m.opacity_logits, 1, 0, sigmoid));
  const char* channels[] = {"r", "g", "b"};
  for (int c = 0; c < 3; ++c) {
    PrintRow(std::string("colour ") + channels[c] + " (DC)",
             Column(m.sh_dc, 3, c, colour));
  }
  RangeStats rest;
  for (float v : m.sh_rest) rest.Add(v, v);
  if (m.sh_degree > 0) PrintRow("f_rest (all)", rest);
  // The norm of the Gaussians whose four values are finite; the count is of
  // values, as in the other rows.
  RangeStats quat_norm;
  for (size_t i = 0; i < m.size(); ++i) {
    const float* q = &m.quats[4 * i];
    size_t bad = 0;
    for (int k = 0; k < 4; ++k) bad += !std::isfinite(q[k]);
    if (bad > 0) {
      quat_norm.non_finite += bad;
      continue;
    }
    quat_norm.Add(0.f, std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] +
                                 double(q[2]) * q[2] + double(q[3]) * q[3]));
  }
  PrintRow("|rot|", quat_norm);
}

int RunPlyInfo(int argc, char** argv) {
  std::string input_path;
  watergs::OptionParser parser(
      "ply_info",
      "Prints a 3DGS model's format, Gaussian count, SH degree, layout, "
      "attribute ranges and NaN/Inf count (PLY, compressed PLY, .spz, "
      ".splat or SOG, told by content).");
  parser.AddRequired(
      "input_path", &input_path,
      "The model file (PLY, compressed PLY, .spz, .splat or SOG)");
  if (!parser.Parse(argc, argv)) return 0;
  watergs::PlyReadOptions options;
  options.allow_non_finite = true;  // report them instead of refusing
  const watergs::ModelData data = watergs::ReadModelFile(input_path, options);
  const bool ply = data.format == watergs::GaussianFormat::kPly;
  const watergs::GaussianModel& m = data.model;
  const int rest = m.sh_rest_stride();
  std::printf("File:            %s\n", input_path.c_str());
  if (ply) {
    std::printf("Format:          %s %s\n", FormatName(data.layout.format),
                data.layout.format_version.c_str());
  } else {
    std::printf("Format:          %s\n", data.format_detail.c_str());
  }
  std::printf("File size:       %llu bytes (header %llu)\n",
              static_cast<unsigned long long>(data.file_size),
              static_cast<unsigned long long>(data.header_size));
  std::printf("Gaussians:       %zu\n", m.size());
  std::printf("SH degree:       %d (%d f_rest)\n", m.sh_degree, rest);
  if (m.size() > 0) {
    std::printf("Bytes/Gaussian:  %.2f (vertex data %.2f)\n",
                double(data.file_size) / m.size(),
                double(data.file_size - data.header_size) / m.size());
  }
  if (ply) {
    std::printf("Properties (%zu): %s\n", data.layout.properties.size(),
                DescribeProperties(data.layout.properties).c_str());
    std::vector<watergs::PlyProperty> extras;
    for (int p : data.layout.ExtraPropertyIndices()) {
      extras.push_back(data.layout.properties[p]);
    }
    std::printf("Extra properties: %s\n",
                extras.empty() ? "none" : DescribeProperties(extras).c_str());
  }
  std::printf("NaN/Inf values:  %zu\n", data.non_finite_count);
  std::printf("Infinities read as +-20: %zu (opacity logits, log-scales)\n",
              data.replaced_infinities);
  PrintRanges(m);
  const auto [implausible, total] = CountImplausible(m);
  if (implausible > total / 10) {
    std::fflush(stdout);
    std::fprintf(
        stderr,
        "warning: %zu of %zu values (%.0f%%) are NaN/Inf or beyond 1e6 in "
        "magnitude: not a trained 3DGS model, or %s\n",
        implausible, total, 100.0 * implausible / total,
        data.layout.format == watergs::PlyFormat::kAscii
            ? "its values are garbage"
            : "the header's byte order is wrong (try the other binary_*)");
  }
  return 0;
}

}  // namespace

WATERGS_COMMAND(
    ply_info, "Prints a 3DGS model's format, count, SH degree, ranges, NaN/Inf",
    RunPlyInfo);
