// Image files as the pipeline reads and writes them: decoding to float RGB
// in [0, 1] (8- or 16-bit files, EXIF orientation ignored as COLMAP does)
// and atomic writing in the format the file name asks for. Shared by the
// workspace loader and the commands that write image sets.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "gaussian/image.h"

namespace watergs {

// The file as float RGB (CV_32FC3, values as stored / 255 or / 65535);
// Error naming the file if it cannot be read or decoded.
cv::Mat DecodeImageFile(const std::string& path);

// A CV_32FC3 RGB image as an ImageRGB, clamped to [0, 1].
ImageRGB ToImageRGB(const cv::Mat& rgb);

// DecodeImageFile then ToImageRGB.
ImageRGB ReadImageFile(const std::string& path);

// Writes `image` (values clamped to [0, 1], 8 bits per channel) atomically
// in `format` (".png", ".jpg"; empty: from the name's extension, any case):
// PNG, or JPEG at quality 100; Error for other formats.
void WriteImageFile(const std::string& path, const ImageRGB& image,
                    std::string format = "");

}  // namespace watergs
