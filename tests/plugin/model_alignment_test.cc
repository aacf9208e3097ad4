// Tests of plugin/model_alignment.h: the similarity between two clouds found
// without correspondences; a model moved into another frame (SH degree 0-3)
// placed back on its photos; another scene's model refused; and `embed`,
// `extract --raw_path` and `eval` on a model saved in another frame, whose
// output stays in that frame and layout.
#include "plugin/model_alignment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "distortion/file_attacks.h"
#include "gaussian/cpu_rasterizer.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/error.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "tests/plugin/rendered_workspace.h"

namespace watergs {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

SimilarityTransform RandomSimilarity(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> log_scale(std::log(0.05),
                                                   std::log(20.0));
  SimilarityTransform t;
  const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng),
                             normal(rng));
  t.rotation = q.normalized().toRotationMatrix();
  t.scale = std::exp(log_scale(rng));
  t.translation = 3 * Vector3d(normal(rng), normal(rng), normal(rng));
  return t;
}

double RotationErrorDegrees(const Matrix3d& a, const Matrix3d& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle() * 180 / M_PI;
}

// An anisotropic cloud with structure and no symmetry: points on the faces
// of a 6 x 4 x 2 box, and a fifth of them on a pole standing on one corner.
std::vector<float> BoxCloud(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  const float half[3] = {3, 2, 1};
  std::vector<float> xyz;
  for (int i = 0; i < n; ++i) {
    float p[3] = {half[0] * u(rng), half[1] * u(rng), half[2] * u(rng)};
    p[i % 3] = (i / 3) % 2 ? half[i % 3] : -half[i % 3];
    if (i % 5 == 4) p[0] = 3, p[1] = 2, p[2] = 2 + u(rng);
    xyz.insert(xyz.end(), p, p + 3);
  }
  return xyz;
}

std::vector<float> Transformed(const std::vector<float>& xyz,
                               const SimilarityTransform& t) {
  std::vector<float> out(xyz.size());
  for (size_t i = 0; i < xyz.size(); i += 3) {
    const Vector3d x =
        t.scale * t.rotation * Vector3d(xyz[i], xyz[i + 1], xyz[i + 2]) +
        t.translation;
    for (int d = 0; d < 3; ++d) out[i + d] = float(x[d]);
  }
  return out;
}

TEST(AlignPointClouds, RecoversRandomSimilaritiesDespiteNoiseAndOutliers) {
  std::mt19937 rng(5);
  const std::vector<float> source = BoxCloud(3000, 1);
  for (int trial = 0; trial < 6; ++trial) {
    const SimilarityTransform truth = RandomSimilarity(rng);
    // Another sampling of the same surfaces (not the same points), 1%
    // noise, and 15% floaters far from them, as Gaussians are to SfM points.
    std::vector<float> target = Transformed(BoxCloud(2500, 100 + trial), truth);
    std::normal_distribution<float> noise(0, 0.01f * truth.scale);
    for (float& v : target) v += noise(rng);
    std::uniform_real_distribution<double> far(-8, 8);
    for (int k = 0; k < 450; ++k) {
      const Vector3d x = truth.scale * Vector3d(far(rng), far(rng), far(rng)) +
                         truth.translation;
      target.insert(target.end(), {float(x[0]), float(x[1]), float(x[2])});
    }
    const std::vector<CloudAlignment> found = AlignPointClouds(source, target);
    ASSERT_FALSE(found.empty());
    const SimilarityTransform& t = found[0].transform;
    EXPECT_NEAR(t.scale / truth.scale, 1, 0.01) << "trial " << trial;
    EXPECT_LT(RotationErrorDegrees(t.rotation, truth.rotation), 1)
        << "trial " << trial;
    EXPECT_LT((t.translation - truth.translation).norm(), 0.03 * truth.scale)
        << "trial " << trial;
  }
}

TEST(AlignPointClouds, RefusesCollapsedClouds) {
  const std::vector<float> point(300, 1.f);
  EXPECT_THROW(AlignPointClouds(point, BoxCloud(100, 1)), Error);
  EXPECT_THROW(AlignPointClouds({1, 2, 3}, BoxCloud(100, 1)), Error);
}

// A workspace's cameras with photos rendered from `model`.
InMemoryViews RenderedViews(const Workspace& workspace,
                            const GaussianModel& model) {
  InMemoryViews views;
  auto rasterizer = MakeCpuRasterizer();
  for (size_t v = 0; v < workspace.NumViews(); ++v) {
    ImageRGB image;
    rasterizer->Forward(model, workspace.ViewCamera(v), RenderOptions{}, &image,
                        nullptr);
    views.Add(workspace.ViewName(v), workspace.ViewCamera(v), image);
  }
  return views;
}

testing::SyntheticModelOptions SceneOptions(int seed) {
  testing::SyntheticModelOptions options = testing::SmallSceneOptions();
  options.num_points = 400;
  options.width = 64;
  options.height = 48;
  options.seed = seed;
  return options;
}

class PlaceModelTest : public ::testing::TestWithParam<int> {};

TEST_P(PlaceModelTest, FindsTheFrameOfAMovedModel) {
  TempDir dir("place_model");
  GaussianModel truth;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", SceneOptions(3), &truth);
  WorkspaceOptions wo;
  wo.workspace_path = ws;
  const Workspace workspace = Workspace::Open(wo);
  std::vector<float> sfm, rgb;
  workspace.PointCloud(&sfm, &rgb);
  // The model at the parameter's SH degree, view-dependent colour included.
  const int degree = GetParam();
  std::mt19937 rng(degree);
  GaussianModel model = truth;
  model.sh_degree = degree;
  model.sh_rest.assign(model.size() * model.sh_rest_stride(), 0.f);
  std::uniform_real_distribution<float> u(-0.15f, 0.15f);
  for (float& c : model.sh_rest) c = u(rng);
  const InMemoryViews photos = RenderedViews(workspace, model);
  auto rasterizer = MakeCpuRasterizer();

  const ModelPlacement same =
      PlaceModel(*rasterizer, model, "model.ply", photos, sfm);
  EXPECT_FALSE(same.moved);
  EXPECT_GT(same.psnr_as_given, 40);
  EXPECT_GT(same.correlation_as_given, 0.999);

  for (int trial = 0; trial < 2; ++trial) {
    const SimilarityTransform truth_move = RandomSimilarity(rng);
    GaussianModel moved = model;
    ApplySimilarity(truth_move, &moved);
    const ModelPlacement p =
        PlaceModel(*rasterizer, moved, "moved.ply", photos, sfm);
    ASSERT_TRUE(p.moved) << DescribePlacement(p);
    EXPECT_LT(p.correlation_as_given, 0.7) << DescribePlacement(p);
    EXPECT_GT(p.correlation_placed, 0.95) << DescribePlacement(p);
    EXPECT_GT(p.psnr_placed, 30) << DescribePlacement(p);
    EXPECT_NEAR(p.workspace_to_model.scale / truth_move.scale, 1, 0.02);
    EXPECT_LT(RotationErrorDegrees(p.workspace_to_model.rotation,
                                   truth_move.rotation),
              1.5);
    EXPECT_NE(DescribePlacement(p).find("aligned"), std::string::npos);
  }
}

INSTANTIATE_TEST_SUITE_P(ShDegrees, PlaceModelTest,
                         ::testing::Values(0, 1, 2, 3));

TEST(PlaceModel, RefusesAnotherScenesModelInOneLine) {
  TempDir dir("place_other");
  GaussianModel ours, other;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", SceneOptions(3), &ours);
  testing::MakeRenderedWorkspace(dir / "other", SceneOptions(11), &other);
  WorkspaceOptions wo;
  wo.workspace_path = ws;
  const Workspace workspace = Workspace::Open(wo);
  const WorkspaceViews views(workspace);
  std::vector<float> sfm, rgb;
  workspace.PointCloud(&sfm, &rgb);
  auto rasterizer = MakeCpuRasterizer();
  try {
    PlaceModel(*rasterizer, other, "other.ply", views, sfm);
    FAIL() << "another scene's model was accepted";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("other.ply: does not match the workspace's photos", 0),
              0u)
        << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(AlignedViews, MovesCamerasNotPhotos) {
  InMemoryViews base;
  RenderCamera camera;
  camera.width = 4;
  camera.height = 3;
  camera.fx = camera.fy = 4;
  camera.t = Vector3d(0, 0, 2);
  base.Add("a", camera, ImageRGB(4, 3));
  SimilarityTransform t;
  t.scale = 2;
  t.translation = Vector3d(1, 0, 0);
  const AlignedViews aligned(base, t);
  EXPECT_EQ(aligned.Image(0), base.Image(0));
  const Vector3d centre = aligned.Camera(0).Center();
  EXPECT_LT((centre - (2 * camera.Center() + t.translation)).norm(), 1e-12);
  // Inverse undoes it.
  const SimilarityTransform back = Inverse(t);
  EXPECT_LT(
      (back.scale * back.rotation * centre + back.translation - camera.Center())
          .norm(),
      1e-12);
}

// The user's case: a splat saved in another frame, in its own layout, handed
// to embed with no option; the written file stays in that frame and layout,
// and the owner reads it with extract --raw_path and eval.
TEST(ModelAlignmentCli, EmbedsAndReadsAModelSavedInAnotherFrame) {
  TempDir dir("align_cli");
  GaussianModel truth;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", SceneOptions(3), &truth);
  std::mt19937 rng(7);
  const SimilarityTransform move = RandomSimilarity(rng);
  ApplySimilarity(move, &truth);
  const std::string raw =
      testing::WriteAsciiPlyWithNormals(dir / "raw.ply", truth);
  const std::string decoder = testing::WriteTinyDecoder(dir / "decoder.bin");
  const std::string wm = dir / "wm.ply";
  const auto run = RunCommand(
      WatergsBin() + " embed --input_path " + raw + " --workspace_path " + ws +
      " --decoder " + decoder + " --message hex:a5c3 --output_path " + wm +
      " --iterations 6 --check_every 3 --check_views 2 --num_threads 2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("embed: the model is in another frame and was "
                            "aligned to the workspace"),
            std::string::npos)
      << run.output;
  const PlyData in = ReadPly(raw), out = ReadPly(wm);
  EXPECT_EQ(out.layout.format, PlyFormat::kAscii);
  EXPECT_EQ(out.layout.extra_values, in.layout.extra_values);
  ASSERT_EQ(out.model.size(), in.model.size());
  // Still in the input's frame: each centre moved by a small fraction of
  // the scene (the frame's scale), not by the similarity.
  double largest = 0;
  for (size_t i = 0; i < in.model.means.size(); ++i) {
    largest = std::max<double>(
        largest, std::abs(out.model.means[i] - in.model.means[i]));
  }
  EXPECT_LT(largest, 0.05 * move.scale);
  // The same frame found for the raw model when reading as the owner.
  const auto extract =
      RunCommand(WatergsBin() + " extract --input_path " + wm + " --raw_path " +
                 raw + " --workspace_path " + ws + " --decoder " + decoder +
                 " --message hex:a5c3");
  ASSERT_EQ(extract.exit_code, 0) << extract.output;
  EXPECT_NE(extract.output.find("extract: the model is in another frame"),
            std::string::npos)
      << extract.output;
  // Taken as it is (--align off), the workspace's cameras see nothing the
  // photos show; eval's PSNR against the photos tells.
  const auto off =
      RunCommand(WatergsBin() + " eval --raw_path " + raw + " --input_path " +
                 wm + " --workspace_path " + ws + " --decoder " + decoder +
                 " --message hex:a5c3 --attacks identity"
                 " --lpips_weights '' --align off");
  const auto on =
      RunCommand(WatergsBin() + " eval --raw_path " + raw + " --input_path " +
                 wm + " --workspace_path " + ws + " --decoder " + decoder +
                 " --message hex:a5c3 --attacks identity"
                 " --lpips_weights ''");
  ASSERT_EQ(off.exit_code, 0) << off.output;
  ASSERT_EQ(on.exit_code, 0) << on.output;
  EXPECT_EQ(off.output.find("another frame"), std::string::npos);
  EXPECT_NE(on.output.find("eval: the model is in another frame"),
            std::string::npos)
      << on.output;
}

}  // namespace
}  // namespace watergs
