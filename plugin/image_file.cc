// Image file writing (see image_file.h).
#include "plugin/image_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {

void WriteImageFile(const std::string& path, const ImageRGB& image,
                    std::string format, int jpeg_quality) {
  std::string ext = format.empty()
                        ? std::filesystem::path(path).extension().string()
                        : format;
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  std::vector<int> params;
  if (ext == ".jpg" || ext == ".jpeg") {
    if (jpeg_quality < 1 || jpeg_quality > 100) {
      FailAt(path, "JPEG quality " + std::to_string(jpeg_quality) +
                       " is not in 1..100");
    }
    params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
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
