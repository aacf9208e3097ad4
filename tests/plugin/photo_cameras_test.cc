// Which photos share a camera: EXIF cameras read back from JPEGs written with
// libexif (and none from PNGs, stripped or broken files), the grouping by
// EXIF camera and size, and the cameras shared in a COLMAP database.
#include "plugin/photo_cameras.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "plugin/colmap_database.h"
#include "tests/plugin/exif_photo.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

using testing::TempDir;

const cv::Mat& SmallPhoto() {
  static const cv::Mat photo(24, 32, CV_8UC3, cv::Scalar(40, 120, 200));
  return photo;
}

TEST(ReadExifCamera, ReadsMakeModelAndFocalLength) {
  TempDir dir("exif_camera");
  const std::string path = (dir / "a.jpg");
  ASSERT_TRUE(testing::WriteJpegWithExif(
      path, SmallPhoto(),
      testing::ExifCameraBlock("Canon", "Canon EOS 5D", 24)));
  const std::optional<ExifCamera> camera = ReadExifCamera(path);
  ASSERT_TRUE(camera.has_value());
  EXPECT_EQ(camera->make, "Canon");
  EXPECT_EQ(camera->model, "Canon EOS 5D");
  EXPECT_DOUBLE_EQ(camera->focal_length_mm, 24.0);
  EXPECT_EQ(camera->Label(), "Canon EOS 5D 24 mm");
  // The photo still decodes with its APP1 segment.
  EXPECT_EQ(cv::imread(path).cols, 32);
}

TEST(ReadExifCamera, PaddingIsTrimmedAndAMissingFocalLengthIsZero) {
  TempDir dir("exif_padding");
  const std::string path = (dir / "a.jpg");
  ASSERT_TRUE(testing::WriteJpegWithExif(
      path, SmallPhoto(), testing::ExifCameraBlock("DJI  ", "FC220", 0)));
  const std::optional<ExifCamera> camera = ReadExifCamera(path);
  ASSERT_TRUE(camera.has_value());
  EXPECT_EQ(camera->make, "DJI");
  EXPECT_EQ(camera->focal_length_mm, 0);
  EXPECT_EQ(camera->Label(), "DJI FC220");
}

TEST(ReadExifCamera, NoneFromPhotosThatNameNoCamera) {
  TempDir dir("exif_none");
  const std::string plain = (dir / "plain.jpg");
  ASSERT_TRUE(testing::WriteJpegWithExif(plain, SmallPhoto(), {}));
  EXPECT_FALSE(ReadExifCamera(plain).has_value());
  const std::string png = (dir / "a.png");
  ASSERT_TRUE(cv::imwrite(png, SmallPhoto()));
  EXPECT_FALSE(ReadExifCamera(png).has_value());
  EXPECT_FALSE(ReadExifCamera((dir / "missing.jpg")).has_value());
  // An EXIF block cut short and one of random bytes: no camera, no crash
  // (these fail only by crashing or by inventing the camera).
  std::vector<unsigned char> block =
      testing::ExifCameraBlock("Canon", "Canon EOS 5D", 24);
  block.resize(block.size() / 3);
  const std::string cut = (dir / "cut.jpg");
  ASSERT_TRUE(testing::WriteJpegWithExif(cut, SmallPhoto(), block));
  const std::optional<ExifCamera> from_cut = ReadExifCamera(cut);
  if (from_cut) {
    EXPECT_TRUE(from_cut->make.empty() || from_cut->make == "Canon");
  }
  std::vector<unsigned char> garbage = {'E', 'x', 'i', 'f', 0, 0};
  for (int k = 0; k < 200; ++k) garbage.push_back((k * 73 + 11) & 0xFF);
  const std::string noise = (dir / "noise.jpg");
  ASSERT_TRUE(testing::WriteJpegWithExif(noise, SmallPhoto(), garbage));
  const std::optional<ExifCamera> from_noise = ReadExifCamera(noise);
  EXPECT_FALSE(from_noise.has_value() && from_noise->make == "Canon");
}

PhotoDescription Photo(int width, std::optional<ExifCamera> exif = {}) {
  return {width, width * 3 / 4, std::move(exif)};
}

const ExifCamera kCanon{"Canon", "Canon EOS 5D", 24};
const ExifCamera kPhone{"Apple", "iPhone 12", 4.2};

TEST(GroupPhotosByCamera, ACaptureInOrderOfOneSizeSharesOneCamera) {
  const PhotoCameras plain =
      GroupPhotosByCamera({Photo(480), Photo(480), Photo(480)}, true);
  EXPECT_EQ(plain.num_groups, 1);
  EXPECT_EQ(plain.group, (std::vector<int>{0, 0, 0}));
  // One EXIF camera, a photo stripped of it: still one walk, one camera.
  const PhotoCameras one = GroupPhotosByCamera(
      {Photo(480, kCanon), Photo(480), Photo(480, kCanon)}, true);
  EXPECT_EQ(one.num_groups, 1);
  EXPECT_EQ(one.num_exif_cameras, 1);
}

TEST(GroupPhotosByCamera, TwoEXIFCamerasOrTwoSizesAreTwoCameras) {
  // In order, one size, but two EXIF cameras: each its own camera.
  const PhotoCameras two = GroupPhotosByCamera(
      {Photo(480, kCanon), Photo(480, kPhone), Photo(480, kCanon)}, true);
  EXPECT_EQ(two.num_groups, 2);
  EXPECT_EQ(two.group[0], two.group[2]);
  EXPECT_NE(two.group[0], two.group[1]);
  // One EXIF camera at two sizes (a copy resized): two cameras.
  const PhotoCameras sizes = GroupPhotosByCamera(
      {Photo(480, kCanon), Photo(360, kCanon), Photo(480, kCanon)}, true);
  EXPECT_FALSE(sizes.one_size);
  EXPECT_EQ(sizes.num_groups, 2);
  EXPECT_EQ(sizes.group[0], sizes.group[2]);
  // One body, another focal length (a zoom): another camera.
  ExifCamera zoomed = kCanon;
  zoomed.focal_length_mm = 70;
  EXPECT_EQ(GroupPhotosByCamera({Photo(480, kCanon), Photo(480, zoomed)}, false)
                .num_groups,
            2);
}

TEST(GroupPhotosByCamera, ACollectionSharesByEXIFCameraAndGivesTheRestOneEach) {
  const PhotoCameras web = GroupPhotosByCamera(
      {Photo(480, kCanon), Photo(480), Photo(480, kPhone), Photo(480, kCanon),
       Photo(480), Photo(480, kPhone), Photo(480, kCanon)},
      false);
  EXPECT_EQ(web.num_exif_cameras, 2);
  EXPECT_EQ(web.num_without_exif, 2);
  EXPECT_EQ(web.num_groups, 4);
  EXPECT_EQ(web.group[0], web.group[3]);
  EXPECT_EQ(web.group[0], web.group[6]);
  EXPECT_EQ(web.group[2], web.group[5]);
  EXPECT_EQ(std::set<int>(web.group.begin(), web.group.end()).size(), 4u);
  EXPECT_NE(web.group[1], web.group[4]);
  // The most photographed camera first.
  EXPECT_EQ(web.summary.rfind("3 of Canon EOS 5D 24 mm 480x360", 0), 0u)
      << web.summary;
  EXPECT_NE(web.summary.find("2 photo(s) without an EXIF camera"),
            std::string::npos)
      << web.summary;
  // An EXIF camera without a focal length (a zoom's setting unknown): a
  // camera each, as without EXIF.
  const ExifCamera no_focal{"Canon", "Canon EOS 5D", 0};
  EXPECT_EQ(
      GroupPhotosByCamera({Photo(480, no_focal), Photo(480, no_focal)}, false)
          .num_groups,
      2);
  // No EXIF at all, in no order: a camera per photo.
  EXPECT_EQ(GroupPhotosByCamera({Photo(480), Photo(480), Photo(480)}, false)
                .num_groups,
            3);
}

// A database with COLMAP's cameras and images tables: image k, named
// "p<k>.jpg", has its own camera k + 1, `widths[k]` x 90.
void WriteCameraDatabase(const std::string& path,
                         const std::vector<int>& widths) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  std::string sql =
      "CREATE TABLE cameras (camera_id INTEGER PRIMARY KEY, model INTEGER, "
      "width INTEGER, height INTEGER, params BLOB, prior_focal_length "
      "INTEGER); CREATE TABLE images (image_id INTEGER PRIMARY KEY, name "
      "TEXT, camera_id INTEGER);";
  for (size_t k = 0; k < widths.size(); ++k) {
    const std::string id = std::to_string(k + 1);
    sql += "INSERT INTO cameras VALUES (" + id + ", 2, " +
           std::to_string(widths[k]) + ", 90, NULL, 0); INSERT INTO images " +
           "VALUES (" + id + ", 'p" + std::to_string(k) + ".jpg', " + id + ");";
  }
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
}

// image name -> camera id, and the camera count.
std::pair<std::map<std::string, int>, int> ReadCameras(
    const std::string& path) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  std::map<std::string, int> of;
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, "SELECT name, camera_id FROM images", -1, &s, nullptr);
  while (sqlite3_step(s) == SQLITE_ROW) {
    of[reinterpret_cast<const char*>(sqlite3_column_text(s, 0))] =
        sqlite3_column_int(s, 1);
  }
  sqlite3_finalize(s);
  sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM cameras", -1, &s, nullptr);
  sqlite3_step(s);
  const int count = sqlite3_column_int(s, 0);
  sqlite3_finalize(s);
  sqlite3_close(db);
  return {of, count};
}

TEST(ShareCameras, GroupsShareTheFirstsCameraAndTheRestAreDeleted) {
  TempDir dir("share_cameras");
  const std::string db = (dir / "database.db");
  ASSERT_NO_FATAL_FAILURE(WriteCameraDatabase(db, {120, 120, 90, 120, 90}));
  EXPECT_EQ(ShareCameras(db, {{"p0.jpg", "p1.jpg", "p3.jpg"}, {"p2.jpg"}})
                .num_cameras,
            3);
  auto [of, count] = ReadCameras(db);
  EXPECT_EQ(count, 3);
  EXPECT_EQ(of["p1.jpg"], 1);
  EXPECT_EQ(of["p3.jpg"], 1);
  EXPECT_EQ(of["p2.jpg"], 3);
  EXPECT_EQ(of["p4.jpg"], 5);
  // Again: nothing changes.
  EXPECT_EQ(ShareCameras(db, {{"p0.jpg", "p1.jpg", "p3.jpg"}}).num_cameras, 3);
  EXPECT_EQ(ReadCameras(db).first, of);
}

TEST(ShareCameras, AnotherSizeFailsAndChangesNothing) {
  TempDir dir("share_cameras_bad");
  const std::string db = dir / "database.db";
  ASSERT_NO_FATAL_FAILURE(WriteCameraDatabase(db, {120, 120, 90}));
  const auto before = ReadCameras(db);
  try {
    ShareCameras(db, {{"p0.jpg", "p1.jpg", "p2.jpg"}});
    ADD_FAILURE() << "two sizes shared a camera";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("photos of two sizes"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(db), std::string::npos) << e.what();
  }
  // The first update (p1 onto p0's camera) was rolled back with the rest.
  EXPECT_EQ(ReadCameras(db), before);
  EXPECT_THROW(ShareCameras(dir / "missing.db", {{"a", "b"}}), std::exception);
  EXPECT_FALSE(std::filesystem::exists(dir / "missing.db"));
}

// COLMAP's extractor skips a file it cannot read: its name is reported and
// left out, the rest of its group still shares a camera.
TEST(ShareCameras, ANameNotInTheDatabaseIsLeftOut) {
  TempDir dir("share_cameras_missing");
  const std::string db = dir / "database.db";
  ASSERT_NO_FATAL_FAILURE(WriteCameraDatabase(db, {120, 120, 120}));
  const SharedCameras shared =
      ShareCameras(db, {{"nowhere.jpg", "p0.jpg", "p2.jpg"}});
  EXPECT_EQ(shared.missing, std::vector<std::string>{"nowhere.jpg"});
  EXPECT_EQ(shared.num_cameras, 2);
  auto [of, count] = ReadCameras(db);
  EXPECT_EQ(of["p2.jpg"], 1);
  EXPECT_EQ(of["p1.jpg"], 2);
}

}  // namespace
}  // namespace watergs
