// Tests of registering images without a pose (plugin/image_registration.h)
// on the embedded demo scene: a photo left out of the index, the same photo
// cropped or shrunk (the copies a leak holds), and an image of nothing; and
// an index of renders only (AddRenders), on a textured room whose geometry
// is known; the index written to a file and read back (detect's cache).
#include "plugin/image_registration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "gaussian/depth_render.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/training_views.h"
#include "tests/common/flat_gaussians.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/image_attacks.h"

namespace watergs {
namespace {

struct DemoWorkspace {
  Workspace workspace;
  WorkspaceViews views;
  DemoWorkspace() : workspace(Open()), views(workspace) {}
  static Workspace Open() {
    WorkspaceOptions o;
    o.workspace_path =
        std::string(WATERGS_SOURCE_DIR) + "/datasets_scripts/demo_scene";
    o.downscale = 2;
    return Workspace::Open(o);
  }
};

// Mean distance (pixels) between where `camera` and `truth` put the SfM
// points that view `view` observes: how far a render at the recovered
// camera would sit from the image. `truth` is the view's camera, cropped or
// scaled as the image was.
double MeanProjectionGap(const DemoWorkspace& d, size_t view,
                         const RenderCamera& camera,
                         const RenderCamera& truth) {
  const Reconstruction& model = d.workspace.reconstruction();
  double sum = 0;
  int n = 0;
  for (const Point2D& p : d.workspace.ViewImage(view).points2D) {
    if (!p.HasPoint3D() || !model.ExistsPoint3D(p.point3D_id)) continue;
    const Eigen::Vector3d X = model.GetPoint3D(p.point3D_id).xyz;
    const Eigen::Vector3d a = camera.R * X + camera.t;
    const Eigen::Vector3d b = truth.R * X + truth.t;
    const Eigen::Vector2d pa(camera.fx * a.x() / a.z() + camera.cx,
                             camera.fy * a.y() / a.z() + camera.cy);
    const Eigen::Vector2d pb(truth.fx * b.x() / b.z() + truth.cx,
                             truth.fy * b.y() / b.z() + truth.cy);
    if (pb.x() < 0 || pb.y() < 0 || pb.x() > truth.width ||
        pb.y() > truth.height) {
      continue;
    }
    sum += (pa - pb).norm();
    ++n;
  }
  EXPECT_GT(n, 20);
  return sum / std::max(n, 1);
}

TEST(ImageRegistration, PhotosLeftOutOfTheIndexRegisterWhereTheyWereTaken) {
  DemoWorkspace d;
  std::vector<double> gaps;  // pixels, every image registered below
  for (size_t view : {size_t(8), size_t(21), size_t(40)}) {
    RegistrationOptions options;
    options.skip_views = {view};
    const ImageRegistrar registrar(d.workspace, d.views, options);
    EXPECT_GT(registrar.IndexSize(), 1000u);
    const RenderCamera truth = d.views.Camera(view);
    const ImageRGB photo = *d.views.Image(view);

    const Registration whole = registrar.Register(photo);
    ASSERT_TRUE(whole.registered) << view << ": " << whole.why;
    EXPECT_GE(whole.inliers, options.min_inliers);
    EXPECT_LT(whole.rms_px, 1.5);
    EXPECT_LT(MeanProjectionGap(d, view, whole.camera, truth), 1.0) << view;
    EXPECT_LT((whole.camera.Center() - truth.Center()).norm(),
              0.02 * d.workspace.SceneExtent())
        << view;

    // The centred 80% window: the same pose, the principal point moved.
    ImageAttackSpec crop{ImageAttackKind::kCrop, 0.8};
    const ImageRGB cropped = ApplyImageAttack(crop, photo);
    RenderCamera cropped_truth = truth;
    cropped_truth.width = cropped.width;
    cropped_truth.height = cropped.height;
    cropped_truth.cx -= (photo.width - cropped.width) / 2;
    cropped_truth.cy -= (photo.height - cropped.height) / 2;
    const Registration c = registrar.Register(cropped);
    ASSERT_TRUE(c.registered) << view << " cropped: " << c.why;
    EXPECT_LT(MeanProjectionGap(d, view, c.camera, cropped_truth), 1.5) << view;

    // Shrunk to 75%: focal length and principal point scale.
    ImageAttackSpec resize{ImageAttackKind::kResize, 0.75};
    const ImageRGB small = ApplyImageAttack(resize, photo);
    RenderCamera small_truth = truth;
    const double sx = double(small.width) / photo.width;
    const double sy = double(small.height) / photo.height;
    small_truth.width = small.width;
    small_truth.height = small.height;
    small_truth.fx *= sx;
    small_truth.cx *= sx;
    small_truth.fy *= sy;
    small_truth.cy *= sy;
    const Registration s = registrar.Register(small);
    ASSERT_TRUE(s.registered) << view << " resized: " << s.why;
    EXPECT_LT(MeanProjectionGap(d, view, s.camera, small_truth), 1.5) << view;
    gaps.push_back(MeanProjectionGap(d, view, whole.camera, truth));
    gaps.push_back(MeanProjectionGap(d, view, c.camera, cropped_truth));
    gaps.push_back(MeanProjectionGap(d, view, s.camera, small_truth));
  }
  // The owner's reading subtracts a render at the recovered camera, so a
  // fraction of a pixel matters: 0.20 px measured over these 9 images, 0.35
  // with SIFT's positions taken in OpenCV's pixel convention, 0.34 with the
  // half-pixel shift alone.
  double mean = 0;
  for (double g : gaps) mean += g / gaps.size();
  EXPECT_LT(mean, 0.25);
}

TEST(ImageRegistration, AnImageOfNothingIsNotRegisteredAndSaysWhy) {
  DemoWorkspace d;
  const ImageRegistrar registrar(d.workspace, d.views);
  ImageRGB noise(240, 180);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  for (float& v : noise.data) v = u(rng);
  const Registration r = registrar.Register(noise);
  EXPECT_FALSE(r.registered);
  EXPECT_NE(r.why.find("needed"), std::string::npos) << r.why;
  const Registration flat = registrar.Register(ImageRGB(240, 180));
  EXPECT_FALSE(flat.registered);
  EXPECT_EQ(flat.matches, 0);
}

// Every field of two cameras equal, to the last bit.
void ExpectSameCamera(const RenderCamera& a, const RenderCamera& b,
                      const std::string& what) {
  EXPECT_EQ(a.width, b.width) << what;
  EXPECT_EQ(a.height, b.height) << what;
  EXPECT_EQ(a.fx, b.fx) << what;
  EXPECT_EQ(a.fy, b.fy) << what;
  EXPECT_EQ(a.cx, b.cx) << what;
  EXPECT_EQ(a.cy, b.cy) << what;
  EXPECT_EQ(a.R, b.R) << what;
  EXPECT_EQ(a.t, b.t) << what;
}

// The index written by Save and read by Load registers images exactly as
// the registrar that wrote it: detect reads its index from a cache and must
// read the same bits as when it built it.
TEST(ImageRegistration, AnIndexReadBackRegistersExactlyAsTheOneSaved) {
  DemoWorkspace d;
  RegistrationOptions options;
  options.skip_views = {21};
  const ImageRegistrar built(d.workspace, d.views, options);
  testing::TempDir dir("registration_index");
  const std::string path = dir / "index.idx";
  built.Save(path);
  const ImageRegistrar read = ImageRegistrar::Load(path, options);
  EXPECT_EQ(read.IndexSize(), built.IndexSize());
  // SIFT's descriptors are integers in [0, 255]: one byte each on disk.
  EXPECT_LT(ReadFileBytes(path).size(), built.IndexSize() * (128 + 24 + 1));

  const ImageRGB photo = *d.views.Image(21);
  ImageAttackSpec crop{ImageAttackKind::kCrop, 0.8};
  const std::vector<std::pair<std::string, ImageRGB>> queries = {
      {"photo", photo}, {"cropped", ApplyImageAttack(crop, photo)}};
  for (const auto& [what, image] : queries) {
    const Registration a = built.Register(image);
    const Registration b = read.Register(image);
    ASSERT_TRUE(a.registered) << what << ": " << a.why;
    ASSERT_TRUE(b.registered) << what << ": " << b.why;
    EXPECT_EQ(a.matches, b.matches) << what;
    EXPECT_EQ(a.inliers, b.inliers) << what;
    EXPECT_EQ(a.rms_px, b.rms_px) << what;
    EXPECT_EQ(a.depth, b.depth) << what;
    ExpectSameCamera(a.camera, b.camera, what);
    ExpectSameCamera(a.guessed_camera, b.guessed_camera, what + " guessed");
    ASSERT_EQ(a.alternatives.size(), b.alternatives.size()) << what;
    for (size_t k = 0; k < a.alternatives.size(); ++k) {
      ExpectSameCamera(a.alternatives[k], b.alternatives[k], what + " alt");
    }
  }
  // Written again, the index read back is the same file.
  read.Save(dir / "again.idx");
  EXPECT_EQ(ReadFileBytes(dir / "again.idx"), ReadFileBytes(path));
}

// Load refuses, in one line "<path>: <problem>", a file that is not an
// index, is cut short or was changed (a bit flipped anywhere: the
// checksum).
TEST(ImageRegistration, AnIndexFileCutOrCorruptedIsRefusedInOneLineNamingIt) {
  DemoWorkspace d;
  testing::TempDir dir("registration_index_bad");
  const std::string good = dir / "good.idx";
  ImageRegistrar(d.workspace, d.views).Save(good);
  const std::vector<uint8_t> bytes = ReadFileBytes(good);
  ASSERT_GT(bytes.size(), 10000u);
  const auto write = [&](const std::string& name,
                         const std::vector<uint8_t>& content) {
    const std::string path = dir / name;
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(content.data()),
               std::streamsize(content.size()));
    return path;
  };
  const auto expect_refused = [](const std::string& path,
                                 const std::string& problem) {
    try {
      ImageRegistrar::Load(path);
      ADD_FAILURE() << path << " was read";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  };
  expect_refused(dir / "missing.idx", "");
  const auto cut = [&](size_t size) {
    return std::vector<uint8_t>(bytes.begin(), bytes.begin() + size);
  };
  expect_refused(write("half.idx", cut(bytes.size() / 2)), "truncated");
  expect_refused(write("last_byte.idx", cut(bytes.size() - 1)), "truncated");
  expect_refused(write("header.idx", cut(12)), "truncated");
  expect_refused(write("empty.idx", {}), "truncated");
  const std::string text = "not an index\n";
  expect_refused(write("text.idx", {text.begin(), text.end()}),
                 "not a watergs registration index");
  // One bit changed in a descriptor, in a point, in the checksum itself.
  for (const size_t at :
       {bytes.size() / 3, bytes.size() - 20, bytes.size() - 1}) {
    std::vector<uint8_t> changed = bytes;
    changed[at] ^= 0x10;
    expect_refused(write("changed.idx", changed), "checksum mismatch");
  }
  std::vector<uint8_t> newer = bytes;
  newer[8] = 2;  // the format version
  expect_refused(write("newer.idx", newer), "format version 2");
  // The good file still reads.
  EXPECT_GT(ImageRegistrar::Load(good).IndexSize(), 1000u);
}

// A room of Gaussians: four walls 3 units from the origin and a floor, each
// a grid of small opaque Gaussians coloured by a few random waves and noise
// (texture SIFT finds at several scales).
GaussianModel TexturedRoom() {
  GaussianModel m;
  m.sh_degree = 0;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  const double spacing = 0.04;
  auto add = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& a,
                 const Eigen::Vector3d& b, double la, double lb) {
    const Eigen::Vector3d n = a.cross(b).normalized();
    double phase[3][3];
    for (auto& row : phase) {
      for (double& p : row) p = 6.28 * u(rng);
    }
    for (double s = 0; s <= la; s += spacing) {
      for (double t = 0; t <= lb; t += spacing) {
        std::array<float, 3> rgb;
        for (int c = 0; c < 3; ++c) {
          const double wave = std::sin(2.1 * s + phase[c][0]) *
                                  std::cos(1.7 * t + phase[c][1]) +
                              0.5 * std::sin(7.3 * (s + t) + phase[c][2]);
          const double v = 0.5 + 0.2 * wave + 0.25 * (u(rng) - 0.5);
          rgb[c] = float(std::clamp(v, 0.0, 1.0));
        }
        AppendFlatGaussian(&m, origin + s * a + t * b, n, 0.7 * spacing,
                           0.7 * spacing * std::exp(-3.0), 5.f, rgb);
      }
    }
  };
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(),
                        Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  add({-3, -3, -1}, X, Z, 6, 2.5);  // y = -3
  add({-3, 3, -1}, X, Z, 6, 2.5);   // y = +3
  add({-3, -3, -1}, Y, Z, 6, 2.5);  // x = -3
  add({3, -3, -1}, Y, Z, 6, 2.5);   // x = +3
  add({-3, -3, -1}, X, Y, 6, 6);    // the floor
  return m;
}

// A 240 x 180 camera at `centre` looking along the horizontal direction
// `heading` (radians from +x), tilted down a little; z up in the world.
RenderCamera RoomCamera(const Eigen::Vector3d& centre, double heading) {
  RenderCamera c;
  c.width = 240;
  c.height = 180;
  c.fx = c.fy = 200;
  c.cx = 120;
  c.cy = 90;
  const Eigen::Vector3d forward(std::cos(heading), std::sin(heading), -0.25);
  const Eigen::Vector3d z = forward.normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  c.R.row(0) = x;
  c.R.row(1) = y;
  c.R.row(2) = z;
  c.t = -c.R * centre;
  return c;
}

// Renders near a viewpoint register an image taken there: the index holds
// only features of renders lifted through their depth (RenderDepth), the
// image is a render from a viewpoint none of them has (between two, nearer
// the wall), shrunk as a screenshot would be.
TEST(ImageRegistration, AnIndexOfRendersPlacesAViewNoPhotoWasTakenFrom) {
  const GaussianModel room = TexturedRoom();
  auto rasterizer = MakeCpuRasterizer();
  const auto render = [&](const RenderCamera& camera) {
    ImageRGB image;
    rasterizer->Forward(room, camera, RenderOptions{}, &image, nullptr);
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    return image;
  };
  const auto depth = [&](const RenderCamera& camera) {
    return RenderDepth(*rasterizer, room, camera);
  };
  // Renders every 30 degrees from a circle of radius 1 around the room's
  // centre, looking out.
  std::vector<RenderCamera> index_cameras;
  for (int k = 0; k < 12; ++k) {
    const double a = k * M_PI / 6;
    index_cameras.push_back(RoomCamera({std::cos(a), std::sin(a), 0.2}, a));
  }
  ImageRegistrar registrar(index_cameras[0]);
  EXPECT_FALSE(registrar.Register(render(index_cameras[0])).registered)
      << "an empty index registered an image";
  registrar.AddRenders(index_cameras, render, depth);
  EXPECT_GT(registrar.IndexSize(), 1000u);

  // 15 degrees from both nearest renders, 0.6 units nearer the wall.
  const RenderCamera truth = RoomCamera(
      {1.3 * std::cos(0.26), 1.3 * std::sin(0.26) + 0.3, 0.35}, M_PI / 12);
  // A render of the index is placed exactly (its features are the index's).
  const Registration same = registrar.Register(render(index_cameras[1]));
  ASSERT_TRUE(same.registered) << same.why;
  EXPECT_LT((same.camera.Center() - index_cameras[1].Center()).norm(), 1e-3);

  const Registration r = registrar.Register(render(truth));
  ASSERT_TRUE(r.registered) << r.why;
  EXPECT_GE(r.inliers, 30);
  // The pose at the known intrinsics (guessed_camera; the refined focal
  // length trades against depth on these walls: 125 px for a 4% lower RMS).
  // Measured 0.024 units and 0.47 degrees: the expected depth of a render is
  // biased toward the nearer Gaussians on a wall seen obliquely (the lifted
  // points ~1% near), which the photometric refinement then takes out.
  EXPECT_LT((r.guessed_camera.Center() - truth.Center()).norm(), 0.05);
  EXPECT_LT(Eigen::AngleAxisd(r.guessed_camera.R * truth.R.transpose()).angle(),
            0.015);  // radians

  // The same view at 75%: the focal length guessed for a resize.
  ImageAttackSpec resize{ImageAttackKind::kResize, 0.75};
  const Registration small =
      registrar.Register(ApplyImageAttack(resize, render(truth)));
  ASSERT_TRUE(small.registered) << small.why;
  EXPECT_LT((small.guessed_camera.Center() - truth.Center()).norm(), 0.05);
  EXPECT_NEAR(small.guessed_camera.fx, 0.75 * truth.fx, 0.01 * truth.fx);
}

}  // namespace
}  // namespace watergs
