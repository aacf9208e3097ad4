// Image files as every command reads them (training ground truth,
// make_decoder, decoder_stats, train_decoder's photos, detect): PNG or JPEG
// (any format OpenCV decodes), 8 or 16 bits per channel, EXIF orientation
// ignored as COLMAP ignores it (workspace images must match COLMAP's
// cameras, and a photo must decode the same in every command), to float RGB
// in [0, 1] (value / 255 or / 65535). Truncated PNG and JPEG files are
// refused rather than decoded with a grey or missing bottom.
// plugin/image_file.h writes images.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "gaussian/image.h"

namespace watergs {

// The file as float RGB (CV_32FC3; 8-bit values / 255.f, 16-bit / 65535.f,
// exactly); Error naming the file if it is missing, not an image, truncated
// or cannot be decoded.
cv::Mat DecodeImageFile(const std::string& path);

// A CV_32FC3 RGB image as an ImageRGB, clamped to [0, 1]; Error (one line)
// for any other cv::Mat type.
ImageRGB ToImageRGB(const cv::Mat& rgb);

// DecodeImageFile then ToImageRGB.
ImageRGB ReadImageFile(const std::string& path);

// Whether the name ends in .png, .jpg or .jpeg (any case).
bool HasImageExtension(const std::string& path);

// The .png/.jpg/.jpeg files in `dir` (and its subfolders when `recursive`),
// sorted by path; Error naming `dir` if it is not a folder.
std::vector<std::string> ListImageFiles(const std::string& dir, bool recursive);

}  // namespace watergs
