// Attacks on 3DGS files beyond the paper's distortion layers (see
// file_attacks.h).
#include "distortion/file_attacks.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>

#include "distortion/chunk_quantize.h"
#include "distortion/decimate.h"
#include "distortion/significance_prune.h"
#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/formats/sog_io.h"
#include "gaussian/formats/splat_io.h"
#include "gaussian/formats/spz_io.h"
#include "gaussian/rasterizer.h"
#include "gaussian/sh.h"
#include "gaussian/util/error.h"
#include "gaussian/util/text_util.h"

namespace watergs {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Parses a whole string as a finite double; `what` names it in the error.
double ParseNumber(const std::string& text, const std::string& what) {
  const std::optional<double> value = ParseFiniteDouble(text);
  if (!value) {
    Fail("--attack: " + what + ": '" + Printable(text) + "' is not a number");
  }
  return *value;
}

std::vector<double> ParseNumbers(const std::string& text,
                                 const std::string& what) {
  std::vector<double> values;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    values.push_back(ParseNumber(item, what));
  }
  return values;
}

void IdentitySource(size_t n, std::vector<uint32_t>* source) {
  source->resize(n);
  std::iota(source->begin(), source->end(), 0u);
}

// Unit directions spread over the sphere (Fibonacci lattice).
Eigen::Vector3d SphereDirection(int j, int count) {
  const double z = 1.0 - (2.0 * j + 1.0) / count;
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double phi = j * kPi * (3.0 - std::sqrt(5.0));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Matrix M of SH band l (coefficients l^2 .. l^2 + 2l) with c' = M c, so that
// sum_k c'_k Y_k(d) = sum_k c_k Y_k(rotation^T d) for every direction d. Each
// band is closed under rotation, so fitting on more directions than
// coefficients recovers M exactly (up to rounding).
Eigen::MatrixXd ShBandRotation(int band, const Eigen::Matrix3d& rotation) {
  const int width = 2 * band + 1, first = band * band;
  const int samples = 4 * width;
  Eigen::MatrixXd at_d(samples, width), at_rotated(samples, width);
  for (int j = 0; j < samples; ++j) {
    const Eigen::Vector3d d = SphereDirection(j, samples);
    const Eigen::Vector3d back = rotation.transpose() * d;
    double basis[16], rotated_basis[16];
    ShBasis(3, d.x(), d.y(), d.z(), basis);
    ShBasis(3, back.x(), back.y(), back.z(), rotated_basis);
    for (int k = 0; k < width; ++k) {
      at_d(j, k) = basis[first + k];
      at_rotated(j, k) = rotated_basis[first + k];
    }
  }
  return at_d.colPivHouseholderQr().solve(at_rotated);
}

void RotateShRest(const Eigen::Matrix3d& rotation, GaussianModel* model) {
  const int stride = model->sh_rest_stride();
  for (int band = 1; band <= model->sh_degree; ++band) {
    const Eigen::MatrixXd m = ShBandRotation(band, rotation);
    const int width = 2 * band + 1, first = band * band;
    for (size_t i = 0; i < model->size(); ++i) {
      float* rest = &model->sh_rest[i * stride];
      for (int ch = 0; ch < 3; ++ch) {
        Eigen::VectorXd c(width);
        for (int k = 0; k < width; ++k) c[k] = rest[(first + k - 1) * 3 + ch];
        const Eigen::VectorXd rotated = m * c;
        for (int k = 0; k < width; ++k) {
          rest[(first + k - 1) * 3 + ch] = float(rotated[k]);
        }
      }
    }
  }
}

// Quantises column `column` of an array of rows of `stride` floats.
void QuantizeColumn(int bits, int stride, int column,
                    std::vector<float>* values) {
  const size_t rows = values->size() / stride;
  if (rows == 0) return;
  double lo = (*values)[column], hi = lo;
  for (size_t i = 0; i < rows; ++i) {
    const double v = (*values)[i * stride + column];
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  const double step = (hi - lo) / double((1 << bits) - 1);
  if (!(step > 0) || !std::isfinite(step)) return;
  for (size_t i = 0; i < rows; ++i) {
    float& v = (*values)[i * stride + column];
    const double level = std::round((double(v) - lo) / step);
    v = float(std::clamp(lo + level * step, lo, hi));
  }
}

void QuantizeArray(int bits, int stride, std::vector<float>* values) {
  for (int column = 0; column < stride; ++column) {
    QuantizeColumn(bits, stride, column, values);
  }
}

// out's Gaussian i = in's Gaussian order[i].
void GatherRows(const GaussianModel& in, const std::vector<uint32_t>& order,
                GaussianModel* out) {
  out->sh_degree = in.sh_degree;
  out->Resize(order.size());
  const int rest = in.sh_rest_stride();
  for (size_t i = 0; i < order.size(); ++i) {
    const size_t s = order[i];
    std::copy_n(&in.means[s * 3], 3, &out->means[i * 3]);
    std::copy_n(&in.log_scales[s * 3], 3, &out->log_scales[i * 3]);
    std::copy_n(&in.quats[s * 4], 4, &out->quats[i * 4]);
    std::copy_n(&in.sh_dc[s * 3], 3, &out->sh_dc[i * 3]);
    std::copy_n(in.sh_rest.data() + s * rest, rest,
                out->sh_rest.data() + i * rest);
    out->opacity_logits[i] = in.opacity_logits[s];
  }
}

// Splits "name:args" into its two parts (args empty without ':').
void SplitNameArgs(const std::string& text, std::string* name,
                   std::string* args) {
  const size_t colon = text.find(':');
  *name = text.substr(0, colon);
  *args = colon == std::string::npos ? "" : text.substr(colon + 1);
}

}  // namespace

SimilarityTransform SimilarityTransform::After(
    const SimilarityTransform& first) const {
  SimilarityTransform composed;
  composed.scale = scale * first.scale;
  composed.rotation = rotation * first.rotation;
  composed.translation = scale * rotation * first.translation + translation;
  return composed;
}

SimilarityTransform ParseSimilarity(const std::string& text) {
  const std::vector<double> v = ParseNumbers(text, "similarity");
  if (v.size() != 5 && v.size() != 8) {
    Fail("--attack: similarity:" + Printable(text) +
         ": expected DEG,TX,TY,TZ,S or DEG,TX,TY,TZ,S,AX,AY,AZ");
  }
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  if (v.size() == 8) axis = Eigen::Vector3d(v[5], v[6], v[7]);
  // Stable norm: an axis like (3, 4, 2e171) must not overflow to inf.
  if (!(axis.stableNorm() > 0)) {
    Fail("--attack: similarity:" + Printable(text) +
         ": the rotation axis is zero");
  }
  if (!(v[4] > 0)) {
    Fail("--attack: similarity:" + Printable(text) + ": the scale must be > 0");
  }
  SimilarityTransform transform;
  transform.rotation =
      Eigen::AngleAxisd(v[0] * kPi / 180.0, axis.stableNormalized())
          .toRotationMatrix();
  transform.translation = Eigen::Vector3d(v[1], v[2], v[3]);
  transform.scale = v[4];
  return transform;
}

std::string ToString(const SimilarityTransform& transform) {
  const Eigen::AngleAxisd angle_axis(transform.rotation);
  const Eigen::Vector3d& t = transform.translation;
  // The axis scaled so that its largest component is +-1: (1,1,1), not
  // (0.577..., ...). Ten digits keep cameras exact to far below a pixel.
  const Eigen::Vector3d a =
      angle_axis.axis() / angle_axis.axis().cwiseAbs().maxCoeff();
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer),
                "%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g",
                angle_axis.angle() * 180.0 / kPi, t.x(), t.y(), t.z(),
                transform.scale, a.x(), a.y(), a.z());
  return buffer;
}

RenderCamera TransformCamera(const RenderCamera& camera,
                             const SimilarityTransform& transform) {
  // X_cam scaled by s: R X + t = (R rot^T (X' - tr)) / s + t.
  RenderCamera moved = camera;
  moved.R = camera.R * transform.rotation.transpose();
  moved.t = transform.scale * camera.t - moved.R * transform.translation;
  moved.near_plane = camera.near_plane * transform.scale;
  moved.far_plane = camera.far_plane * transform.scale;
  return moved;
}

void ApplySimilarity(const SimilarityTransform& transform,
                     GaussianModel* model) {
  const Eigen::Quaterniond q_rotation(transform.rotation);
  const float log_scale = float(std::log(transform.scale));
  for (size_t i = 0; i < model->size(); ++i) {
    float* mean = &model->means[i * 3];
    const Eigen::Vector3d moved =
        transform.scale * transform.rotation *
            Eigen::Vector3d(mean[0], mean[1], mean[2]) +
        transform.translation;
    for (int k = 0; k < 3; ++k) {
      mean[k] = float(moved[k]);
      model->log_scales[i * 3 + k] += log_scale;
    }
    float* q = &model->quats[i * 4];
    const Eigen::Quaterniond rotated =
        q_rotation * Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
    q[0] = float(rotated.w());
    q[1] = float(rotated.x());
    q[2] = float(rotated.y());
    q[3] = float(rotated.z());
  }
  RotateShRest(transform.rotation, model);
}

void TruncateShToDegree0(GaussianModel* model) {
  std::fill(model->sh_rest.begin(), model->sh_rest.end(), 0.f);
}

void QuantizeFloat16(GaussianModel* model) {
  for (std::vector<float>* array :
       {&model->means, &model->log_scales, &model->quats,
        &model->opacity_logits, &model->sh_dc, &model->sh_rest}) {
    for (float& v : *array) {
      v = float(Eigen::half(std::clamp(v, -65504.f, 65504.f)));
    }
  }
}

void QuantizeLinear(int bits, GaussianModel* model) {
  if (bits < 1 || bits > 16) {
    Fail("--attack: quant:" + std::to_string(bits) +
         ": bits must be in [1, 16]");
  }
  QuantizeArray(bits, 3, &model->means);
  QuantizeArray(bits, 3, &model->log_scales);
  QuantizeArray(bits, 4, &model->quats);
  QuantizeArray(bits, 1, &model->opacity_logits);
  QuantizeArray(bits, 3, &model->sh_dc);
  if (model->sh_rest_stride() > 0) {
    QuantizeArray(bits, model->sh_rest_stride(), &model->sh_rest);
  }
}

void ApplyCodec(GaussianFormat codec, int spz_version, const GaussianModel& in,
                GaussianModel* out, std::vector<uint32_t>* source) {
  IdentitySource(in.size(), source);
  std::string bytes;
  auto data = [&bytes] {
    return reinterpret_cast<const uint8_t*>(bytes.data());
  };
  switch (codec) {
    case GaussianFormat::kSpz:
      bytes = EncodeSpz(in, {spz_version});
      *out = DecodeSpz("spz codec", data(), bytes.size());
      break;
    case GaussianFormat::kCompressedPly:
      bytes = EncodeCompressedPly(in, source);
      *out = DecodeCompressedPly("compressed_ply codec", data(), bytes.size());
      break;
    case GaussianFormat::kSplat:
      bytes = EncodeSplat(in);
      // .splat cannot hold 0 Gaussians; the round trip of none is none.
      if (in.size() == 0) {
        *out = GaussianModel();
        out->sh_degree = 0;
      } else {
        *out = DecodeSplat("splat codec", data(), bytes.size());
      }
      break;
    case GaussianFormat::kSog:
      bytes = EncodeSog(in, {}, source);
      *out = DecodeSog("sog codec", data(), bytes.size());
      break;
    case GaussianFormat::kPly:
      *out = in;
      break;
  }
  if (out->sh_degree != in.sh_degree) {
    out->sh_degree = in.sh_degree;
    out->sh_rest.assign(out->size() * out->sh_rest_stride(), 0.f);
  }
}

ModelAttackSpec ParseModelAttack(const std::string& text) {
  std::string name, args;
  SplitNameArgs(text, &name, &args);
  ModelAttackSpec spec;
  const auto no_args = [&] {
    if (!args.empty())
      Fail("--attack: '" + Printable(text) + "' takes no argument");
  };
  if (name == "identity" || name == "gn" || name == "dropout" ||
      name == "crop") {
    spec.kind = ModelAttackKind::kDistortion;
    spec.distortion = ParseDistortionSpec(text);
    MakeDistortionLayer(spec.distortion);  // range check
  } else if (name == "sh0") {
    no_args();
    spec.kind = ModelAttackKind::kShTruncation;
  } else if (name == "fp16") {
    no_args();
    spec.kind = ModelAttackKind::kFloat16;
  } else if (name == "quant") {
    spec.kind = ModelAttackKind::kQuantize;
    if (!args.empty()) {
      const double bits = ParseNumber(args, "quant");
      if (bits != std::round(bits) || bits < 1 || bits > 16) {
        Fail("--attack: '" + Printable(text) +
             "': bits must be an integer in [1, 16]");
      }
      spec.bits = int(bits);
    }
  } else if (name == "shuffle") {
    no_args();
    spec.kind = ModelAttackKind::kShuffle;
  } else if (name == "similarity") {
    spec.kind = ModelAttackKind::kSimilarity;
    spec.similarity = ParseSimilarity(args);
  } else if (name == "prune") {
    spec.kind = ModelAttackKind::kPrune;
    spec.opacity_threshold = ParseNumber(args, "prune");
    if (spec.opacity_threshold < 0 || spec.opacity_threshold > 1) {
      Fail("--attack: '" + Printable(text) +
           "': the opacity threshold must be in [0, 1]");
    }
  } else if (name == "prune_significance" || name == "decimate") {
    spec.kind = name == "decimate" ? ModelAttackKind::kDecimate
                                   : ModelAttackKind::kPruneSignificance;
    spec.fraction = ParseNumber(args, name);
    if (!(spec.fraction >= 0 && spec.fraction < 1)) {
      Fail("--attack: '" + Printable(text) +
           "': the fraction removed must be in [0, 1)");
    }
  } else if (name == "quant_chunk") {
    spec.kind = ModelAttackKind::kQuantizeChunked;
    const size_t colon = args.find(':');
    const std::string bits_text = args.substr(0, colon);
    const double bits = ParseNumber(bits_text, "quant_chunk");
    if (bits != std::round(bits) || bits < 1 || bits > 16) {
      Fail("--attack: '" + Printable(text) +
           "': bits must be an integer in [1, 16]");
    }
    spec.bits = int(bits);
    if (colon != std::string::npos) {
      const double position_bits =
          ParseNumber(args.substr(colon + 1), "quant_chunk position bits");
      if (position_bits != std::round(position_bits) || position_bits < 1 ||
          position_bits > 24) {
        Fail("--attack: '" + Printable(text) +
             "': position bits must be an integer in [1, 24]");
      }
      spec.position_bits = int(position_bits);
    }
  } else if (name == "spz") {
    spec.kind = ModelAttackKind::kCodec;
    spec.codec = GaussianFormat::kSpz;
    if (!args.empty()) {
      if (args != "2" && args != "3") {
        Fail("--attack: '" + Printable(text) + "': SPZ version 2 or 3");
      }
      spec.spz_version = args == "2" ? 2 : 3;
    }
  } else if (name == "compressed_ply" || name == "splat" || name == "sog") {
    no_args();
    spec.kind = ModelAttackKind::kCodec;
    spec.codec = name == "splat" ? GaussianFormat::kSplat
                 : name == "sog" ? GaussianFormat::kSog
                                 : GaussianFormat::kCompressedPly;
  } else {
    Fail("--attack: unknown attack '" + Printable(text) +
         "' (identity, gn:SIGMA, dropout:P, crop:P, sh0, fp16, quant:BITS, "
         "shuffle, similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ], prune:T, "
         "spz[:VERSION], compressed_ply, splat, sog, prune_significance:F, "
         "decimate:F, quant_chunk:BITS[:POSBITS])");
  }
  return spec;
}

std::vector<ModelAttackSpec> ParseModelAttackList(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    const bool continues = !items.empty() && !item.empty() &&
                           (std::isdigit(static_cast<unsigned char>(item[0])) ||
                            item[0] == '-' || item[0] == '+' || item[0] == '.');
    if (continues) {
      items.back() += "," + item;
    } else {
      items.push_back(item);
    }
  }
  if (items.empty()) Fail("--attack: empty attack list");
  std::vector<ModelAttackSpec> specs;
  for (const std::string& one : items) specs.push_back(ParseModelAttack(one));
  return specs;
}

std::string ToString(const ModelAttackSpec& spec) {
  switch (spec.kind) {
    case ModelAttackKind::kDistortion:
      return ToString(spec.distortion);
    case ModelAttackKind::kShTruncation:
      return "sh0";
    case ModelAttackKind::kFloat16:
      return "fp16";
    case ModelAttackKind::kQuantize:
      return "quant:" + std::to_string(spec.bits);
    case ModelAttackKind::kShuffle:
      return "shuffle";
    case ModelAttackKind::kSimilarity:
      return "similarity:" + ToString(spec.similarity);
    case ModelAttackKind::kPrune: {
      std::ostringstream out;
      out << "prune:" << spec.opacity_threshold;
      return out.str();
    }
    case ModelAttackKind::kCodec:
      if (spec.codec == GaussianFormat::kSpz) {
        return "spz:" + std::to_string(spec.spz_version);
      }
      return GaussianFormatName(spec.codec);
    case ModelAttackKind::kPruneSignificance:
    case ModelAttackKind::kDecimate: {
      std::ostringstream out;
      out << (spec.kind == ModelAttackKind::kDecimate ? "decimate:"
                                                      : "prune_significance:")
          << spec.fraction;
      return out.str();
    }
    case ModelAttackKind::kQuantizeChunked:
      return "quant_chunk:" + std::to_string(spec.bits) + ":" +
             std::to_string(spec.position_bits);
  }
  return "?";
}

bool AttackNeedsCameras(const ModelAttackSpec& spec) {
  return spec.kind == ModelAttackKind::kPruneSignificance;
}

bool AttackRendersPerDraw(const ModelAttackSpec& spec) {
  return spec.kind == ModelAttackKind::kDistortion &&
         spec.distortion.kind != DistortionKind::kIdentity;
}

void ApplyModelAttack(const ModelAttackSpec& spec, const GaussianModel& in,
                      std::mt19937_64& rng, GaussianModel* out,
                      std::vector<uint32_t>* source,
                      const std::vector<RenderCamera>* cameras) {
  switch (spec.kind) {
    case ModelAttackKind::kPruneSignificance: {
      if (cameras == nullptr || cameras->empty()) {
        Fail("--attack: " + ToString(spec) +
             " needs the training cameras (--workspace_path)");
      }
      const auto rasterizer = MakeCpuRasterizer();
      PruneLowestScores(spec.fraction,
                        SignificanceScores(in, *cameras, *rasterizer), in, out,
                        source);
      return;
    }
    case ModelAttackKind::kDecimate:
      Decimate(spec.fraction, in, out, source);
      return;
    case ModelAttackKind::kDistortion:
      MakeDistortionLayer(spec.distortion)->Apply(in, rng, out, source);
      return;
    case ModelAttackKind::kShuffle: {
      IdentitySource(in.size(), source);
      std::shuffle(source->begin(), source->end(), rng);
      GatherRows(in, *source, out);
      return;
    }
    case ModelAttackKind::kPrune: {
      std::vector<bool> keep(in.size());
      source->clear();
      for (size_t i = 0; i < in.size(); ++i) {
        const double opacity = 1.0 / (1.0 + std::exp(-in.opacity_logits[i]));
        keep[i] = opacity >= spec.opacity_threshold;
        if (keep[i]) source->push_back(uint32_t(i));
      }
      *out = in;
      out->Filter(keep);
      return;
    }
    case ModelAttackKind::kCodec:
      ApplyCodec(spec.codec, spec.spz_version, in, out, source);
      return;
    default:
      break;
  }
  *out = in;
  IdentitySource(in.size(), source);
  if (spec.kind == ModelAttackKind::kShTruncation) TruncateShToDegree0(out);
  if (spec.kind == ModelAttackKind::kFloat16) QuantizeFloat16(out);
  if (spec.kind == ModelAttackKind::kQuantize) QuantizeLinear(spec.bits, out);
  if (spec.kind == ModelAttackKind::kQuantizeChunked) {
    QuantizeChunked(spec.bits, spec.position_bits, out);
  }
  if (spec.kind == ModelAttackKind::kSimilarity) {
    ApplySimilarity(spec.similarity, out);
  }
}

}  // namespace watergs
