// Image file decoding and writing (see image_file.h).
#include "plugin/image_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "gaussian/error.h"
#include "gaussian/file_util.h"

namespace watergs {

cv::Mat DecodeImageFile(const std::string& path) {
  const cv::Mat raw = cv::imread(path, cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH |
                                           cv::IMREAD_IGNORE_ORIENTATION);
  if (raw.empty()) FailAt(path, "cannot read or decode image");
  const double scale = raw.depth() == CV_16U  ? 1.0 / 65535
                       : raw.depth() == CV_8U ? 1.0 / 255
                                              : 1.0;
  cv::Mat rgb;
  raw.convertTo(rgb, CV_32FC3, scale);
  cv::cvtColor(rgb, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

ImageRGB ToImageRGB(const cv::Mat& rgb) {
  ImageRGB image(rgb.cols, rgb.rows);
  for (int row = 0; row < rgb.rows; ++row) {
    const float* source = rgb.ptr<float>(row);
    std::copy(source, source + 3 * rgb.cols, image.At(0, row));
  }
  for (float& value : image.data) value = std::clamp(value, 0.f, 1.f);
  return image;
}

ImageRGB ReadImageFile(const std::string& path) {
  return ToImageRGB(DecodeImageFile(path));
}

void WriteImageFile(const std::string& path, const ImageRGB& image,
                    std::string format) {
  std::string ext = format.empty()
                        ? std::filesystem::path(path).extension().string()
                        : format;
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  std::vector<int> params;
  if (ext == ".jpg" || ext == ".jpeg") {
    params = {cv::IMWRITE_JPEG_QUALITY, 100};
  } else if (ext != ".png") {
    FailAt(path, "cannot write images of type '" + ext + "' (png, jpg)");
  }
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const float* p = image.At(x, y);
      cv::Vec3b& out = bgr.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        out[2 - c] = static_cast<uint8_t>(
            std::lround(std::clamp(p[c], 0.f, 1.f) * 255.f));
      }
    }
  }
  std::vector<uchar> bytes;
  if (!cv::imencode(ext, bgr, bytes, params)) {
    FailAt(path, "image encoding failed");
  }
  AtomicWriteFile(path, std::string(bytes.begin(), bytes.end()));
}

}  // namespace watergs
