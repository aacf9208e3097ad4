// `reconstruct` with the real COLMAP 3.8 binary on photos that do not share a
// size: 12 of the demo's photos, named in capture order, two of them shrunk to
// 75% (another camera, or a copy resized on its way). The plan must not
// declare one camera, and the two must come out with a camera of their own
// size, apart from the others'.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "plugin/reconstruction_io.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

TEST(ReconstructCameras, PhotosOfAnotherSizeGetACameraOfTheirOwn) {
  ASSERT_EQ(RunCommand("colmap -h > /dev/null").exit_code, 0)
      << "colmap 3.8 must be on PATH (scripts/install_deps.sh --tests)";
  TempDir dir("reconstruct_cameras");
  const fs::path photos = dir / "photos";
  fs::create_directories(photos);
  const std::set<std::string> shrunk = {"view_003.jpg", "view_008.jpg"};
  for (int k = 0; k < 12; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "view_%03d.jpg", k);
    const fs::path source = fs::path(WATERGS_SOURCE_DIR) /
                            "datasets_scripts/demo_scene/images" / name;
    if (!shrunk.count(name)) {
      fs::copy_file(source, photos / name);
      continue;
    }
    cv::Mat image = cv::imread(source.string());
    ASSERT_FALSE(image.empty()) << source;
    cv::resize(image, image, cv::Size(360, 270), 0, 0, cv::INTER_AREA);
    ASSERT_TRUE(cv::imwrite((photos / name).string(), image,
                            {cv::IMWRITE_JPEG_QUALITY, 95}));
  }
  const auto run =
      RunCommand(WatergsBin() + " reconstruct --image_path " + photos.string() +
                 " --workspace_path " + (dir / "ws"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(run.output.find("one camera (photos share one size)"),
            std::string::npos)
      << run.output;
  const Reconstruction model = ReadReconstruction(dir / "ws/sparse/0");
  ASSERT_GE(model.RegImageIds().size(), 10u) << run.output;
  std::set<camera_t> full_size_cameras;
  int shrunk_registered = 0;
  for (const image_t id : model.RegImageIds()) {
    const Image& image = model.Images().at(id);
    const Camera& camera = model.Cameras().at(image.camera_id);
    if (shrunk.count(image.name)) {
      ++shrunk_registered;
      EXPECT_EQ(camera.width, 360u) << image.name;
      EXPECT_EQ(camera.height, 270u) << image.name;
    } else {
      EXPECT_EQ(camera.width, 480u) << image.name;
      full_size_cameras.insert(image.camera_id);
    }
  }
  EXPECT_EQ(shrunk_registered, 2) << run.output;
  for (const image_t id : model.RegImageIds()) {
    const Image& image = model.Images().at(id);
    if (shrunk.count(image.name)) {
      EXPECT_FALSE(full_size_cameras.count(image.camera_id)) << image.name;
    }
  }
}

}  // namespace
}  // namespace watergs
