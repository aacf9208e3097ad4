// Image file decoding shared by every command (see image_reading.h).
#include "watermark/image_reading.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

bool IsJpeg(const std::vector<uint8_t>& b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}

bool IsPng(const std::vector<uint8_t>& b) {
  static const uint8_t kSignature[8] = {0x89, 'P',  'N',  'G',
                                        0x0D, 0x0A, 0x1A, 0x0A};
  return b.size() >= 8 && std::equal(kSignature, kSignature + 8, b.begin());
}

// Whether the JPEG's segments lead to an end-of-image marker. Segments are
// skipped by their length (so an EXIF thumbnail's own marker is not taken
// for the file's), entropy-coded data up to the next marker; bytes after
// the marker (a motion photo's video) are allowed.
bool JpegHasEnd(const std::vector<uint8_t>& b) {
  const size_t n = b.size();
  size_t i = 2;
  while (i + 1 < n) {
    if (b[i] != 0xFF) {  // not at a marker: resynchronise
      ++i;
      continue;
    }
    const uint8_t marker = b[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0xD9) return true;
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {
      i += 2;  // markers without a length
      continue;
    }
    if (i + 3 >= n) return false;
    i += 2 + ((size_t(b[i + 2]) << 8) | b[i + 3]);
    if (marker == 0xDA) {  // start of scan: entropy-coded data follows
      while (i + 1 < n && !(b[i] == 0xFF && b[i + 1] != 0x00 &&
                            !(b[i + 1] >= 0xD0 && b[i + 1] <= 0xD7))) {
        ++i;
      }
    }
  }
  return false;
}

// Whether the PNG's chunks lead to its IEND chunk.
bool PngHasEnd(const std::vector<uint8_t>& b) {
  size_t i = 8;
  while (i + 8 <= b.size()) {
    const size_t length = (size_t(b[i]) << 24) | (size_t(b[i + 1]) << 16) |
                          (size_t(b[i + 2]) << 8) | b[i + 3];
    if (std::equal(b.begin() + i + 4, b.begin() + i + 8, "IEND")) return true;
    i += 12 + length;
  }
  return false;
}

template <typename T>
void ToFloatRgb(const cv::Mat& bgr, float max_value, cv::Mat* rgb) {
  *rgb = cv::Mat(bgr.rows, bgr.cols, CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y) {
    const T* in = bgr.ptr<T>(y);
    float* out = rgb->ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      for (int c = 0; c < 3; ++c) {
        out[3 * x + c] = float(in[3 * x + 2 - c]) / max_value;
      }
    }
  }
}

}  // namespace

cv::Mat DecodeImageFile(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  if (bytes.empty()) FailAt(path, "empty file, not an image");
  if (IsJpeg(bytes) && !JpegHasEnd(bytes)) {
    FailAt(path, "truncated JPEG (no end-of-image marker)");
  }
  if (IsPng(bytes) && !PngHasEnd(bytes)) {
    FailAt(path, "truncated PNG (no IEND chunk)");
  }
  cv::Mat raw;
  try {
    raw = cv::imdecode(bytes, cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH |
                                  cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception&) {
    raw.release();
  }
  if (raw.empty()) FailAt(path, "cannot decode: not a PNG or JPEG image");
  cv::Mat rgb;
  switch (raw.depth()) {
    case CV_8U:
      ToFloatRgb<uint8_t>(raw, 255.f, &rgb);
      break;
    case CV_16U:
      ToFloatRgb<uint16_t>(raw, 65535.f, &rgb);
      break;
    case CV_32F:
      ToFloatRgb<float>(raw, 1.f, &rgb);
      break;
    default:
      FailAt(path, "unsupported sample type " + cv::typeToString(raw.type()));
  }
  return rgb;
}

ImageRGB ToImageRGB(const cv::Mat& rgb) {
  if (rgb.type() != CV_32FC3) {
    Fail("ToImageRGB: expected a float RGB image (CV_32FC3), got " +
         cv::typeToString(rgb.type()));
  }
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

bool HasImageExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

std::vector<std::string> ListImageFiles(const std::string& dir,
                                        bool recursive) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(dir)) FailAt(dir, "not a folder of images");
  std::vector<std::string> paths;
  const auto add = [&](const fs::directory_entry& entry) {
    if (entry.is_regular_file() && HasImageExtension(entry.path().string())) {
      paths.push_back(entry.path().string());
    }
  };
  if (recursive) {
    for (const auto& entry : fs::recursive_directory_iterator(dir)) add(entry);
  } else {
    for (const auto& entry : fs::directory_iterator(dir)) add(entry);
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

}  // namespace watergs
