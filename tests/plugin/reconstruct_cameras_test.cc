// `reconstruct` with the real COLMAP 3.8 binary on photos that do not share a
// camera. 12 of the demo's photos, named in capture order, two of them shrunk
// to 75% (another camera, or a copy resized on its way): the plan must not
// declare one camera, and the two must come out with a camera of their own
// size, apart from the others'. A collection in no order whose EXIF names two
// cameras: the photos of each share one, and every photo is placed right.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "plugin/reconstruction_io.h"
#include "tests/plugin/exif_photo.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const fs::path kDemo =
    fs::path(WATERGS_SOURCE_DIR) / "datasets_scripts/demo_scene";

std::string ViewName(int k) {
  char name[32];
  std::snprintf(name, sizeof(name), "view_%03d.jpg", k);
  return name;
}

// The demo's photo `k`, shrunk to 75% (360x270) when `shrink`.
cv::Mat DemoPhoto(int k, bool shrink) {
  cv::Mat image = cv::imread((kDemo / "images" / ViewName(k)).string());
  if (shrink && !image.empty()) {
    cv::resize(image, image, cv::Size(360, 270), 0, 0, cv::INTER_AREA);
  }
  return image;
}

TEST(ReconstructCameras, PhotosOfAnotherSizeGetACameraOfTheirOwn) {
  ASSERT_EQ(RunCommand("colmap -h > /dev/null").exit_code, 0)
      << "colmap 3.8 must be on PATH (scripts/install_deps.sh --tests)";
  TempDir dir("reconstruct_cameras");
  const fs::path photos = dir / "photos";
  fs::create_directories(photos);
  const std::set<std::string> shrunk = {"view_003.jpg", "view_008.jpg"};
  for (int k = 0; k < 12; ++k) {
    const std::string name = ViewName(k);
    if (!shrunk.count(name)) {
      fs::copy_file(kDemo / "images" / name, photos / name);
      continue;
    }
    const cv::Mat image = DemoPhoto(k, true);
    ASSERT_FALSE(image.empty()) << name;
    ASSERT_TRUE(cv::imwrite((photos / name).string(), image,
                            {cv::IMWRITE_JPEG_QUALITY, 95}));
  }
  const auto run =
      RunCommand(WatergsBin() + " reconstruct --image_path " + photos.string() +
                 " --workspace_path " + (dir / "ws"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(run.output.find("one camera ("), std::string::npos) << run.output;
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

// Half the demo's circle at both heights (view_000-011, view_024-035, as
// unordered_photos_test) under names in no order, their EXIF naming one
// camera but for two shrunk to 75% whose EXIF names another: the 22 share a
// camera, the two another, and every photo is placed within 2% of the
// capture's size of where it was taken.
TEST(ReconstructCameras, ACollectionsPhotosOfOneEXIFCameraShareACamera) {
  ASSERT_EQ(RunCommand("colmap -h > /dev/null").exit_code, 0)
      << "colmap 3.8 must be on PATH (scripts/install_deps.sh --tests)";
  TempDir dir("reconstruct_exif_cameras");
  const fs::path photos = dir / "photos";
  fs::create_directories(photos);
  const std::vector<std::string> words = {
      "ash",    "birch", "cedar", "dogwood",  "elm",    "fir",
      "ginkgo", "hazel", "ivy",   "juniper",  "kapok",  "larch",
      "maple",  "neem",  "oak",   "pine",     "quince", "rowan",
      "spruce", "teak",  "umbra", "viburnum", "willow", "yew"};
  const std::set<int> shrunk = {5, 29};
  const auto canon = testing::ExifCameraBlock("Canon", "Canon EOS 5D", 35);
  const auto phone = testing::ExifCameraBlock("Apple", "iPhone 12", 4.2);
  std::map<std::string, std::string> renamed;  // view_NNN.jpg -> word.jpg
  for (int n = 0; n < 24; ++n) {
    const int k = n < 12 ? n : n + 12;
    // Every 7th word: the names' order is not the capture's.
    const std::string name = words[(n * 7) % 24] + ".jpg";
    renamed[ViewName(k)] = name;
    const cv::Mat image = DemoPhoto(k, shrunk.count(k));
    ASSERT_FALSE(image.empty()) << ViewName(k);
    ASSERT_TRUE(testing::WriteJpegWithExif((photos / name).string(), image,
                                           shrunk.count(k) ? phone : canon));
  }
  // The ground truth under the new names (images.txt's last field).
  const fs::path truth = dir / "truth";
  fs::create_directories(truth);
  fs::copy_file(kDemo / "ground_truth/cameras.txt", truth / "cameras.txt");
  fs::copy_file(kDemo / "ground_truth/points3D.txt", truth / "points3D.txt");
  std::ifstream in(kDemo / "ground_truth/images.txt");
  std::ofstream out(truth / "images.txt");
  const std::regex view_name(R"(view_\d{3}\.jpg$)");
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_search(line, m, view_name)) {
      if (!renamed.count(m.str())) {  // not one of the 24
        std::getline(in, line);
        continue;
      }
      line = m.prefix().str() + renamed[m.str()];
      out << line << "\n\n";
      std::getline(in, line);  // its (empty) observations line
      continue;
    }
    out << line << "\n";
  }
  out.close();

  const auto run =
      RunCommand(WatergsBin() + " reconstruct --image_path " + photos.string() +
                 " --workspace_path " + (dir / "ws"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("2 cameras for 24 photos, one per EXIF camera"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("22 of Canon EOS 5D 35 mm 480x360, 2 of Apple "
                            "iPhone 12 4.2 mm 360x270"),
            std::string::npos)
      << run.output;
  const Reconstruction model = ReadReconstruction(dir / "ws/sparse/0");
  EXPECT_EQ(model.Cameras().size(), 2u);
  ASSERT_EQ(model.RegImageIds().size(), 24u) << run.output;
  std::set<camera_t> canon_cameras, phone_cameras;
  for (const image_t id : model.RegImageIds()) {
    const Image& image = model.Images().at(id);
    const bool small = image.name == renamed["view_005.jpg"] ||
                       image.name == renamed["view_029.jpg"];
    (small ? phone_cameras : canon_cameras).insert(image.camera_id);
    EXPECT_EQ(model.Cameras().at(image.camera_id).width, small ? 360u : 480u)
        << image.name;
  }
  EXPECT_EQ(canon_cameras.size(), 1u);
  EXPECT_EQ(phone_cameras.size(), 1u);
  EXPECT_NE(*canon_cameras.begin(), *phone_cameras.begin());

  const auto poses =
      RunCommand(WatergsBin() + " model_info --sparse_path " + (dir / "ws") +
                 " --reference_path " + truth.string());
  ASSERT_EQ(poses.exit_code, 0) << poses.output;
  std::smatch worst;
  const std::regex at_most(R"(24 common images.* at most ([0-9.]+)% )");
  ASSERT_TRUE(std::regex_search(poses.output, worst, at_most)) << poses.output;
  EXPECT_LT(std::stod(worst[1]), 2.0) << poses.output;
}

}  // namespace
}  // namespace watergs
