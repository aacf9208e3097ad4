// COLMAP model files: bin <-> txt round trips are lossless and byte-stable,
// formats are detected, workspaces are stepped into, statistics follow
// COLMAP's definitions.
#include "plugin/reconstruction_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/model_analyzer.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

std::string FileText(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  return std::string(bytes.begin(), bytes.end());
}

testing::SyntheticModelOptions AllModels() {
  testing::SyntheticModelOptions options;
  options.model_ids = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  options.num_images = 14;
  options.num_points = 300;
  return options;
}

void ExpectSameModel(const Reconstruction& a, const Reconstruction& b) {
  ASSERT_EQ(a.NumCameras(), b.NumCameras());
  ASSERT_EQ(a.NumRegImages(), b.NumRegImages());
  ASSERT_EQ(a.NumPoints3D(), b.NumPoints3D());
  for (const auto& [id, camera] : a.Cameras()) {
    const Camera& other = b.GetCamera(id);
    EXPECT_EQ(camera.model_id, other.model_id);
    EXPECT_EQ(camera.width, other.width);
    EXPECT_EQ(camera.params, other.params);
  }
  for (const auto& [id, image] : a.Images()) {
    const Image& other = b.GetImage(id);
    EXPECT_EQ(image.name, other.name);
    EXPECT_EQ(image.camera_id, other.camera_id);
    EXPECT_EQ(image.tvec, other.tvec);
    EXPECT_LT((NormalizeQuaternion(image.qvec) - other.qvec).norm(), 1e-15);
    ASSERT_EQ(image.points2D.size(), other.points2D.size());
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      EXPECT_EQ(image.points2D[i].xy, other.points2D[i].xy);
      EXPECT_EQ(image.points2D[i].point3D_id, other.points2D[i].point3D_id);
    }
  }
  for (const auto& [id, point] : a.Points3D()) {
    const Point3D& other = b.GetPoint3D(id);
    EXPECT_EQ(point.xyz, other.xyz);
    EXPECT_EQ(point.rgb, other.rgb);
    EXPECT_EQ(point.error, other.error);
    ASSERT_EQ(point.track.size(), other.track.size());
    for (size_t i = 0; i < point.track.size(); ++i) {
      EXPECT_EQ(point.track[i].image_id, other.track[i].image_id);
      EXPECT_EQ(point.track[i].point2D_idx, other.track[i].point2D_idx);
    }
  }
}

// The text with its data records (one line, or image line + POINTS2D
// line) sorted: COLMAP writes records in std::unordered_map order, which
// changes with every read (colmap model_converter BIN -> BIN reorders too),
// so round trips are compared up to record order, comments in place.
std::string SortedRecords(const std::string& text, int lines_per_record) {
  std::istringstream in(text);
  std::string line, comments;
  std::vector<std::string> records;
  while (std::getline(in, line)) {
    if (line.rfind("#", 0) == 0) {
      comments += line + "\n";
      continue;
    }
    std::string record = line + "\n";
    for (int i = 1; i < lines_per_record && std::getline(in, line); ++i) {
      record += line + "\n";
    }
    records.push_back(record);
  }
  std::sort(records.begin(), records.end());
  for (const std::string& record : records) comments += record;
  return comments;
}

TEST(ReconstructionIO, BinToTxtToBinRoundTripIsExact) {
  testing::TempDir dir("io_bin_txt_bin");
  const Reconstruction original =
      testing::MakeSyntheticReconstruction(AllModels());
  WriteReconstruction(original, dir / "bin1", ModelFormat::kBinary);
  const Reconstruction from_bin = ReadReconstruction(dir / "bin1");
  ExpectSameModel(original, from_bin);
  WriteReconstruction(from_bin, dir / "txt", ModelFormat::kText);
  const Reconstruction from_txt = ReadReconstruction(dir / "txt");
  ExpectSameModel(from_bin, from_txt);
  WriteReconstruction(from_txt, dir / "bin2", ModelFormat::kBinary);
  const Reconstruction from_bin2 = ReadReconstruction(dir / "bin2");
  ExpectSameModel(from_bin, from_bin2);
  WriteReconstruction(from_bin2, dir / "txt2", ModelFormat::kText);
  // Same bytes up to record order; same sizes exactly.
  const std::vector<std::pair<std::string, int>> files = {
      {"cameras", 1}, {"images", 2}, {"points3D", 1}};
  for (const auto& [name, lines_per_record] : files) {
    EXPECT_EQ(fs::file_size(dir / ("bin1/" + name + ".bin")),
              fs::file_size(dir / ("bin2/" + name + ".bin")));
    EXPECT_EQ(SortedRecords(FileText(dir / ("txt/" + name + ".txt")),
                            lines_per_record),
              SortedRecords(FileText(dir / ("txt2/" + name + ".txt")),
                            lines_per_record))
        << name;
  }
  // The same in-memory model always gives the same bytes.
  WriteReconstruction(from_txt, dir / "bin3", ModelFormat::kBinary);
  EXPECT_EQ(FileText(dir / "bin2/points3D.bin"),
            FileText(dir / "bin3/points3D.bin"));
}

TEST(ReconstructionIO, TextKeepsFullPrecisionAndColmapHeaders) {
  testing::TempDir dir("io_text");
  Reconstruction model;
  model.AddCamera({1, 2, 640, 480, {0.1, 320.25, 240, 1e-17}});
  Image image;
  image.image_id = 4;
  image.name = "a.jpg";
  image.camera_id = 1;
  image.tvec << 1.0 / 3, 0, -2;
  image.points2D = {{Eigen::Vector2d(1.5, 2.5), 9}, {Eigen::Vector2d(3, 4)}};
  model.AddImage(image);
  model.RegisterImage(4);
  Point3D point;
  point.xyz << 0.5, -0.25, 7;
  point.rgb << 255, 0, 17;
  point.error = 0.75;
  point.track = {{4, 0}};
  model.AddPoint3D(9, point);
  WriteReconstruction(model, dir.path(), ModelFormat::kText);
  EXPECT_EQ(FileText(dir / "cameras.txt"),
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
            "# Number of cameras: 1\n"
            "1 SIMPLE_RADIAL 640 480 0.10000000000000001 320.25 240 "
            "1.0000000000000001e-17\n");
  EXPECT_EQ(FileText(dir / "images.txt"),
            "# Image list with two lines of data per image:\n"
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
            "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
            "# Number of images: 1, mean observations per image: 1\n"
            "4 1 0 0 0 0.33333333333333331 0 -2 1 a.jpg\n"
            "1.5 2.5 9 3 4 -1\n");
  EXPECT_EQ(FileText(dir / "points3D.txt"),
            "# 3D point list with one line of data per point:\n"
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as "
            "(IMAGE_ID, POINT2D_IDX)\n"
            "# Number of points: 1, mean track length: 1\n"
            "9 0.5 -0.25 7 255 0 17 0.75 4 0\n");
}

TEST(ReconstructionIO, DetectsFormatAndStepsIntoWorkspace) {
  testing::TempDir dir("io_detect");
  const Reconstruction model =
      testing::MakeSyntheticReconstruction(testing::SyntheticModelOptions{});
  WriteReconstruction(model, dir / "ws/sparse/0", ModelFormat::kText);
  EXPECT_EQ(FindModelPath(dir / "ws"), dir / "ws/sparse/0");
  EXPECT_EQ(DetectModelFormat(dir / "ws/sparse/0"), ModelFormat::kText);
  EXPECT_EQ(ReadReconstruction(dir / "ws").NumPoints3D(), model.NumPoints3D());
  WriteReconstruction(model, dir / "ws2/sparse", ModelFormat::kBinary);
  EXPECT_EQ(FindModelPath(dir / "ws2"), dir / "ws2/sparse");
  EXPECT_EQ(DetectModelFormat(dir / "ws2/sparse"), ModelFormat::kBinary);
  EXPECT_EQ(ReadReconstruction(dir / "ws2/sparse").NumRegImages(),
            model.NumRegImages());
  EXPECT_EQ(ParseModelFormat("txt"), ModelFormat::kText);
  EXPECT_THROW(ParseModelFormat("PLY"), Error);
}

TEST(ReconstructionIO, ReadsCommentsBlankLinesAndCrLf) {
  testing::TempDir dir("io_crlf");
  AtomicWriteFile(dir / "cameras.txt", "# c\r\n\r\n7 PINHOLE 10 8 9 9 5 4\r\n");
  AtomicWriteFile(
      dir / "images.txt",
      "# i\n3 1 0 0 0 0 0 1 7 x.png\n\n5 1 0 0 0 0 0 2 7 my  photo.png\r\n"
      "1 1 -1 2 2 11\n");
  AtomicWriteFile(dir / "points3D.txt", "11 0 0 3 1 2 3 -1 5 1\n");
  const Reconstruction model = ReadReconstruction(dir.path());
  EXPECT_EQ(model.NumRegImages(), 2u);
  EXPECT_TRUE(model.GetImage(3).points2D.empty());
  EXPECT_EQ(model.GetImage(5).points2D.size(), 2u);
  EXPECT_EQ(model.GetImage(5).name, "my  photo.png");
  EXPECT_EQ(model.GetPoint3D(11).track[0].image_id, 5u);
  EXPECT_FALSE(model.GetPoint3D(11).HasError());
}

TEST(ReconstructionIO, StatisticsFollowColmapDefinitions) {
  Reconstruction model;
  model.AddCamera({1, 0, 100, 100, {50, 50, 50}});
  for (image_t id : {1, 2, 3}) {
    Image image;
    image.image_id = id;
    image.name = std::to_string(id);
    image.camera_id = 1;
    // 2 observed keypoints and one unobserved per image.
    image.points2D = {{{1, 1}, 10}, {{2, 2}, 20}, {{3, 3}}};
    model.AddImage(image);
    if (id != 3) model.RegisterImage(id);  // image 3 is not registered
  }
  Point3D a, b, c;
  a.error = 1.0;
  b.error = 2.5;
  model.AddPoint3D(10, a);
  model.AddPoint3D(20, b);
  model.AddPoint3D(30, c);  // no error: excluded from the mean
  const ModelSummary summary = AnalyzeModel(model);
  EXPECT_EQ(summary.num_images, 3u);
  EXPECT_EQ(summary.num_reg_images, 2u);
  EXPECT_EQ(summary.num_observations, 4u);
  EXPECT_DOUBLE_EQ(summary.mean_track_length, 4.0 / 3);
  EXPECT_DOUBLE_EQ(summary.mean_observations_per_image, 2.0);
  EXPECT_DOUBLE_EQ(summary.mean_reprojection_error, 1.75);
  EXPECT_NE(FormatModelSummary(summary).find("Mean track length: 1.333333\n"),
            std::string::npos);
}

}  // namespace
}  // namespace watergs
