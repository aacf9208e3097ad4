// Whether a 3DGS model belongs to a workspace's cameras, and the similarity
// that puts a model saved in a trainer's own normalised frame back onto them.
// Several trainers save their splats in such a frame by default (OpenSplat
// without --keep-crs, gsplat's simple_trainer with normalize_world_space,
// nerfstudio's dataparser transform): translated, rotated and uniformly
// scaled from COLMAP's. watergs then renders the workspace's cameras moved
// into the model's frame, so the model itself is never touched and the
// watermarked file stays in the user's frame.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "distortion/file_attacks.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"

namespace watergs {

// The views of `base` seen from its cameras moved by `workspace_to_model`
// (TransformCamera): the workspace's photos, rendered in the model's frame.
class AlignedViews : public TrainingViews {
 public:
  AlignedViews(const TrainingViews& base,
               const SimilarityTransform& workspace_to_model)
      : base_(base), transform_(workspace_to_model) {}
  size_t NumViews() const override { return base_.NumViews(); }
  std::string Name(size_t view) const override { return base_.Name(view); }
  RenderCamera Camera(size_t view) const override;
  std::shared_ptr<const ImageRGB> Image(size_t view) const override {
    return base_.Image(view);
  }
  bool HeldOut(size_t view) const override { return base_.HeldOut(view); }

 private:
  const TrainingViews& base_;
  SimilarityTransform transform_;
};

struct PhotoMatch {
  // Means over the views: PSNR (dB) and Pearson's correlation over every
  // pixel and channel (0 where either image is flat).
  double psnr = 0, correlation = 0;
};

// How `model`'s whole-frame renders at `view_ids` of `views` match their
// photos.
PhotoMatch MatchPhotos(Rasterizer& rasterizer, const GaussianModel& model,
                       const TrainingViews& views,
                       const std::vector<size_t>& view_ids,
                       const std::array<float, 3>& background);

struct CloudAlignment {
  // source -> target.
  SimilarityTransform transform;
  // Median distance between each point and its nearest neighbour in the
  // other cloud after the transform (both directions), as a fraction of the
  // target's median distance from its centre: 0 for identical clouds.
  double residual = 0;
};

// Points are N x 3 (x0 y0 z0 x1 ...), each at least 10. Finds the similarity
// taking `source` onto `target` without correspondences: starts from the
// clouds' robust centres and principal axes (every proper signed permutation
// of the axes, and of the world axes) and refines each by trimmed,
// symmetric ICP with scale (Umeyama); returns the `keep` best, best first.
std::vector<CloudAlignment> AlignPointClouds(const std::vector<float>& source,
                                             const std::vector<float>& target,
                                             int keep = 3);

struct PlacementOptions {
  // Views rendered for the check (spread over the workspace's).
  int probe_views = 3;
  // The check measures how well the renders correlate with the photos
  // (Pearson's correlation over every pixel and channel, the mean over the
  // probe views): unlike PSNR it does not depend on how much of a scene is
  // plain background, and a flat image scores 0. Below this correlation the
  // model is searched for a similarity: trained models of the scenes here
  // score 0.9 or more (demo, fern, horns); the same models in a trainer's
  // normalised frame, or another scene, near 0.
  double align_below_correlation = 0.7;
  // A model whose correlation stays below this after the search is refused
  // (another scene's random blobs reached 0.41 in the tests' 64x48 scenes,
  // the models of the right scene 0.95 or more)
  // (with `refuse`; a suspect, which an attack may have damaged, is only
  // warned about).
  double refuse_below_correlation = 0.5;
  bool refuse = true;
  std::array<float, 3> background = {0, 0, 0};
};

struct ModelPlacement {
  // Maps workspace coordinates into the model's frame (identity when the
  // model was already in the workspace's frame).
  SimilarityTransform workspace_to_model;
  bool moved = false;
  // Mean PSNR and correlation against the photos at the probe views, as
  // given and as placed.
  double psnr_as_given = 0, psnr_placed = 0;
  double correlation_as_given = 0, correlation_placed = 0;
  size_t num_probe_views = 0;
  // ICP residual of the found similarity (CloudAlignment::residual).
  double residual = 0;
  double seconds = 0;
};

// Renders `model` at a few of `views` and, when it does not match their
// photos, aligns its Gaussians' centres to `sfm_points` (the workspace's
// SfM points, N x 3) and keeps the candidate whose renders match best.
// Throws Error naming `model_path` with the figures when nothing matches
// (options.refuse).
ModelPlacement PlaceModel(Rasterizer& rasterizer, const GaussianModel& model,
                          const std::string& model_path,
                          const TrainingViews& views,
                          const std::vector<float>& sfm_points,
                          const PlacementOptions& options = {});

// One line for the user: "the model matches the photos (PSNR X dB at N
// views)" or the alignment found (scale, rotation angle, translation, PSNR
// before and after, residual, time).
std::string DescribePlacement(const ModelPlacement& placement);

// The inverse similarity: x -> (R^T (x - t)) / s.
SimilarityTransform Inverse(const SimilarityTransform& transform);

// "similarity:DEG,TX,TY,TZ,S[,AX,AY,AZ]", the bare numbers, or a file holding
// that line (the .transform.txt `watergs attack` writes): the transform a
// model was moved by from the workspace's frame. `option` names the flag in
// errors. Throws Error.
SimilarityTransform ParseSceneTransform(const std::string& value,
                                        const std::string& option);

// --align's help text, the same in every command that renders a model at the
// workspace's cameras.
extern const char kAlignHelp[];

class Workspace;

// A model placed on a workspace: the views to render it from.
struct PlacedViews {
  ModelPlacement placement;
  const TrainingViews* base = nullptr;
  std::unique_ptr<AlignedViews> aligned;
  const TrainingViews& views() const { return aligned ? *aligned : *base; }
};

// Strengths given in scene units (the noise layer's sigma) rescaled to the
// model's frame: the paper's gn:0.01 is 0.01 of the workspace's units.
void ScaleToModelUnits(const ModelPlacement& placement,
                       std::vector<DistortionSpec>* layers);
void ScaleToModelUnits(const ModelPlacement& placement,
                       std::vector<ModelAttackSpec>* attacks);

// --align: "auto" (PlaceModel; without photos in the workspace nothing is
// checked), "off" (the model is taken as it is), or a scene transform
// (ParseSceneTransform). Prints one line "COMMAND: ..." (DescribePlacement)
// unless off. Throws Error; a `suspect` (not the owner's own model) that
// matches nothing is only warned about on stderr.
PlacedViews PlaceByOption(const std::string& command, const std::string& align,
                          Rasterizer& rasterizer, const GaussianModel& model,
                          const std::string& model_path,
                          const Workspace& workspace,
                          const TrainingViews& views,
                          const std::array<float, 3>& background,
                          bool suspect = false);

}  // namespace watergs
