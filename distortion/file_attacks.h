// Attacks on 3DGS files that users meet beyond the paper's distortion layers:
// SH truncation to degree 0 (what .splat viewers keep), float16 and k-bit
// quantisation of the attributes (global, a stress test; per chunk, as
// compressed formats do), shuffling the Gaussians, a similarity transform of
// the whole scene, pruning by opacity, and the compaction pipeline's
// significance pruning and neighbour-merging decimation. Together with the
// distortion layers (identity, gn, dropout, crop) they form the "model attacks"
// of `watergs attack` and `watergs eval`.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "distortion/distortion_layer.h"
#include "gaussian/camera.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/gaussian_model.h"

namespace watergs {

// x -> scale * rotation * x + translation, applied to the whole scene.
struct SimilarityTransform {
  // Uniform scale factor (> 0).
  double scale = 1.0;
  // Proper rotation (det +1).
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  // Translation after rotation and scaling, scene units.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  // `this` after `first`: x -> this(first(x)).
  SimilarityTransform After(const SimilarityTransform& first) const;
};

// Parses "DEG,TX,TY,TZ,S" (rotation by DEG degrees about the z axis) or
// "DEG,TX,TY,TZ,S,AX,AY,AZ" (about the axis (AX, AY, AZ)); throws Error.
SimilarityTransform ParseSimilarity(const std::string& text);
// "DEG,TX,TY,TZ,S,AX,AY,AZ" with 10 significant digits, the axis scaled to
// a largest component of +-1 (ParseSimilarity's inverse to ~1e-10).
std::string ToString(const SimilarityTransform& transform);

// The camera that sees the transformed scene as `camera` saw the original:
// R' = R rotation^T, t' = scale t - R' translation; near/far scale too.
RenderCamera TransformCamera(const RenderCamera& camera,
                             const SimilarityTransform& transform);

// Moves every Gaussian: means mapped, log-scales + log(scale), quaternions
// pre-multiplied by the rotation, and each SH band rotated so that colour
// seen from the moved cameras is unchanged.
void ApplySimilarity(const SimilarityTransform& transform,
                     GaussianModel* model);

// Zeroes every higher SH coefficient (f_rest): the model keeps its SH degree
// and file layout, and renders exactly as the degree-0 model would.
void TruncateShToDegree0(GaussianModel* model);

// Rounds every attribute to the nearest IEEE float16 (ties to even), values
// beyond the float16 range clamped to +-65504 so they stay finite.
void QuantizeFloat16(GaussianModel* model);

// Per attribute column (x, y, z, each scale, rotation, f_dc and f_rest
// component, opacity): linear quantisation to 2^bits levels between the
// column's min and max, as compressed-PLY formats do; error <= step / 2 with
// step = (max - min) / (2^bits - 1). bits in [1, 16].
void QuantizeLinear(int bits, GaussianModel* model);

enum class ModelAttackKind {
  kDistortion,
  kShTruncation,
  kFloat16,
  kQuantize,
  kShuffle,
  kSimilarity,
  kPrune,
  kCodec,
  kPruneSignificance,
  kDecimate,
  kQuantizeChunked
};

// One attack on a model.
struct ModelAttackSpec {
  // Which attack.
  ModelAttackKind kind = ModelAttackKind::kDistortion;
  // kDistortion: the distortion layer (identity, gn, dropout, crop).
  DistortionSpec distortion;
  // kQuantize, kQuantizeChunked: bits per value.
  int bits = 8;
  // kQuantizeChunked: bits per position coordinate.
  int position_bits = 16;
  // kPruneSignificance, kDecimate: fraction of the Gaussians removed.
  double fraction = 0.0;
  // kPrune: Gaussians with sigmoid(opacity) below this are removed.
  double opacity_threshold = 0.0;
  // kSimilarity: the scene transform.
  SimilarityTransform similarity;
  // kCodec: the file format whose real encoder and decoder are applied
  // (kSpz, kCompressedPly, kSplat or kSog), and the SPZ version (2 or 3).
  GaussianFormat codec = GaussianFormat::kSpz;
  int spz_version = 3;
};

// The model after a round trip through a file format's encoder and decoder
// (in memory): spz (version 2 or 3), compressed_ply and sog (Morton-ordered:
// source gives each output Gaussian's input index) or splat (SH above degree
// 0 dropped, then zero-padded so the model keeps its SH degree and layout).
void ApplyCodec(GaussianFormat codec, int spz_version, const GaussianModel& in,
                GaussianModel* out, std::vector<uint32_t>* source);

// Parses one attack: identity | gn:SIGMA | dropout:P | crop:P | sh0 | fp16 |
// quant:BITS (quant = quant:8) | shuffle | similarity:DEG,TX,TY,TZ,S[,AX,AY,
// AZ] | prune:T | spz[:VERSION] (spz = spz:3) | compressed_ply | splat |
// sog | prune_significance:F | decimate:F | quant_chunk:BITS[:POSBITS] (POSBITS
// 16 by default). Throws Error naming the text.
ModelAttackSpec ParseModelAttack(const std::string& text);
// Comma-separated attacks; an item starting with a digit, sign or '.'
// continues the previous one's arguments (so "similarity:30,1,0,0,2,sh0" is
// two attacks). Throws Error if empty.
std::vector<ModelAttackSpec> ParseModelAttackList(const std::string& text);
// The text ParseModelAttack reads back.
std::string ToString(const ModelAttackSpec& spec);

// Whether the attack renders the scene (prune_significance: it scores the
// Gaussians by their blend weight in the training cameras).
bool AttackNeedsCameras(const ModelAttackSpec& spec);

// Whether the attacked model's renders depend on the random draw: the 3D
// distortions other than identity (a shuffle reorders rows, not the scene).
bool AttackRendersPerDraw(const ModelAttackSpec& spec);

// out = attack(in); source[i] is the index in `in` of output Gaussian i
// (for PlyLayout::RemapExtras). `out` must not alias `in`. `cameras`: the
// training cameras, needed by the attacks AttackNeedsCameras names (Error
// without them), ignored by the others.
void ApplyModelAttack(const ModelAttackSpec& spec, const GaussianModel& in,
                      std::mt19937_64& rng, GaussianModel* out,
                      std::vector<uint32_t>* source,
                      const std::vector<RenderCamera>* cameras = nullptr);

}  // namespace watergs
