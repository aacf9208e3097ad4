// The one image-reading path of every command (watermark/image_reading.h):
// 8- and 16-bit values scaled exactly, EXIF orientation ignored as COLMAP
// ignores it, truncated PNG and JPEG files and non-float matrices refused in
// one line naming the problem.
#include "watermark/image_reading.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "watermark/decoder_training.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

class ImageReadingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("watergs_image_reading_" + std::to_string(std::random_device()()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const {
    return (dir_ / name).string();
  }
  // A w x h BGR image of random bytes (or 16-bit words).
  static cv::Mat Noise(int w, int h, int type) {
    cv::Mat m(h, w, type);
    cv::randu(m, 0, type == CV_16UC3 ? 65536 : 256);
    return m;
  }
  static void WriteBytes(const std::string& path,
                         const std::vector<uint8_t>& bytes) {
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  }
  static std::string ErrorOf(const std::string& path) {
    try {
      DecodeImageFile(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(ImageReadingTest, EightAndSixteenBitValuesAreScaledExactly) {
  const cv::Mat bgr8 = Noise(7, 5, CV_8UC3), bgr16 = Noise(6, 4, CV_16UC3);
  ASSERT_TRUE(cv::imwrite(Path("a.png"), bgr8));
  ASSERT_TRUE(cv::imwrite(Path("b.png"), bgr16));
  const cv::Mat a = DecodeImageFile(Path("a.png"));
  const cv::Mat b = DecodeImageFile(Path("b.png"));
  ASSERT_EQ(a.type(), CV_32FC3);
  ASSERT_EQ(b.type(), CV_32FC3);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(a.at<cv::Vec3f>(y, x)[c],
                  bgr8.at<cv::Vec3b>(y, x)[2 - c] / 255.f);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(b.at<cv::Vec3f>(y, x)[c],
                  bgr16.at<cv::Vec3w>(y, x)[2 - c] / 65535.f);
  const ImageRGB image = ReadImageFile(Path("a.png"));
  EXPECT_EQ(image.width, 7);
  EXPECT_EQ(image.At(3, 2)[0], a.at<cv::Vec3f>(2, 3)[0]);
}

TEST_F(ImageReadingTest, ToImageRgbRefusesAnythingButFloatRgb) {
  // The bug of issue 29: an 8-bit matrix read as floats.
  const cv::Mat bytes = Noise(8, 8, CV_8UC3);
  try {
    ToImageRGB(bytes);
    FAIL() << "8-bit matrix accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(CV_32FC3), got CV_8UC3"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(ToImageRGB(cv::Mat(4, 4, CV_32FC1)), Error);
  EXPECT_THROW(ToImageRGB(cv::Mat(4, 4, CV_64FC3)), Error);
}

// A JPEG whose EXIF says "rotate 90 degrees" (orientation 6) decodes as
// stored, not rotated: COLMAP's cameras see the stored pixels.
TEST_F(ImageReadingTest, ExifOrientationIsIgnoredEverywhere) {
  std::vector<uchar> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", Noise(40, 16, CV_8UC3), jpeg));
  const std::vector<uint8_t> tiff = {
      'I',  'I',  42, 0, 8, 0, 0, 0,  // little-endian TIFF, IFD at 8
      1,    0,                        // one entry
      0x12, 0x01, 3,  0, 1, 0, 0, 0, 6, 0, 0, 0,  // Orientation = 6
      0,    0,    0,  0};                         // no next IFD
  std::vector<uint8_t> app1 = {0xFF, 0xE1, 0, 0, 'E', 'x', 'i', 'f', 0, 0};
  app1.insert(app1.end(), tiff.begin(), tiff.end());
  app1[2] = uint8_t((app1.size() - 2) >> 8);
  app1[3] = uint8_t((app1.size() - 2) & 0xFF);
  std::vector<uint8_t> file(jpeg.begin(), jpeg.begin() + 2);
  file.insert(file.end(), app1.begin(), app1.end());
  file.insert(file.end(), jpeg.begin() + 2, jpeg.end());
  WriteBytes(Path("rotated.jpg"), file);
  // OpenCV's default reading honours the tag: the file is really oriented.
  ASSERT_EQ(cv::imread(Path("rotated.jpg"), cv::IMREAD_COLOR).cols, 16);
  const cv::Mat decoded = DecodeImageFile(Path("rotated.jpg"));
  EXPECT_EQ(decoded.cols, 40);
  EXPECT_EQ(decoded.rows, 16);
  // The photo folder of decoder training reads it the same way.
  const std::vector<cv::Mat> photos = LoadPhotoFolder(dir_.string());
  ASSERT_EQ(photos.size(), 1u);
  EXPECT_EQ(photos[0].cols, 40);
  EXPECT_EQ(photos[0].type(), CV_32FC3);
  EXPECT_EQ(cv::norm(photos[0], decoded, cv::NORM_INF), 0);
}

TEST_F(ImageReadingTest, RefusesTruncatedAndNonImageFilesInOneLine) {
  std::vector<uchar> png, jpeg;
  const cv::Mat noise = Noise(64, 48, CV_8UC3);
  ASSERT_TRUE(cv::imencode(".png", noise, png));
  ASSERT_TRUE(cv::imencode(".jpg", noise, jpeg));
  WriteBytes(Path("half.png"),
             std::vector<uint8_t>(png.begin(), png.begin() + png.size() / 2));
  WriteBytes(
      Path("half.jpg"),
      std::vector<uint8_t>(jpeg.begin(), jpeg.begin() + jpeg.size() / 2));
  // Only the last bytes missing (a JPEG decoder fills the gap in grey; a
  // PNG missing only IEND would decode).
  WriteBytes(Path("cut.jpg"),
             std::vector<uint8_t>(jpeg.begin(), jpeg.end() - 2));
  WriteBytes(Path("cut.png"),
             std::vector<uint8_t>(png.begin(), png.end() - 12));
  WriteBytes(Path("text.png"), {'h', 'e', 'l', 'l', 'o', '\n'});
  WriteBytes(Path("empty.jpg"), {});
  EXPECT_EQ(ErrorOf(Path("half.png")),
            Path("half.png") + ": truncated PNG (no IEND chunk)");
  EXPECT_EQ(ErrorOf(Path("cut.png")),
            Path("cut.png") + ": truncated PNG (no IEND chunk)");
  EXPECT_EQ(ErrorOf(Path("half.jpg")),
            Path("half.jpg") + ": truncated JPEG (no end-of-image marker)");
  EXPECT_EQ(ErrorOf(Path("cut.jpg")),
            Path("cut.jpg") + ": truncated JPEG (no end-of-image marker)");
  EXPECT_EQ(ErrorOf(Path("text.png")),
            Path("text.png") + ": cannot decode: not a PNG or JPEG image");
  EXPECT_EQ(ErrorOf(Path("empty.jpg")),
            Path("empty.jpg") + ": empty file, not an image");
  EXPECT_EQ(ErrorOf(Path("missing.png")),
            Path("missing.png") + ": file not found");
  // Bytes after the end-of-image marker (a motion photo's video) are fine.
  std::vector<uint8_t> tail(jpeg.begin(), jpeg.end());
  tail.insert(tail.end(), 1000, 0x42);
  WriteBytes(Path("tail.jpg"), tail);
  EXPECT_EQ(DecodeImageFile(Path("tail.jpg")).cols, 64);
  // A photo folder names the file it cannot read.
  try {
    LoadPhotoFolder(dir_.string());
    FAIL() << "folder with truncated photos accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).find(dir_.string()), 0u) << e.what();
  }
}

TEST_F(ImageReadingTest, ListsImageFilesSortedByName) {
  fs::create_directories(dir_ / "sub");
  for (const char* name : {"b.PNG", "a.jpeg", "c.txt", "sub/d.jpg"}) {
    WriteBytes(Path(name), {0});
  }
  EXPECT_EQ(ListImageFiles(dir_.string(), false),
            (std::vector<std::string>{Path("a.jpeg"), Path("b.PNG")}));
  EXPECT_EQ(ListImageFiles(dir_.string(), true),
            (std::vector<std::string>{Path("a.jpeg"), Path("b.PNG"),
                                      Path("sub/d.jpg")}));
  EXPECT_THROW(ListImageFiles(Path("a.jpeg"), false), Error);
}

}  // namespace
}  // namespace watergs
