// Image files as the pipeline writes them: atomically, in the format the
// file name asks for. Reading (DecodeImageFile, ReadImageFile, ToImageRGB)
// is one path for every command, in watermark/image_reading.h (decoder
// training reads photos through it too), included here for the callers
// that do both.
#pragma once

#include <string>

#include "gaussian/image.h"
#include "watermark/image_reading.h"

namespace watergs {

// Writes `image` (values clamped to [0, 1], 8 bits per channel) atomically
// in `format` (".png", ".jpg"; empty: from the name's extension, any case):
// PNG, or JPEG at `jpeg_quality` (1..100); Error for other formats.
void WriteImageFile(const std::string& path, const ImageRGB& image,
                    std::string format = "", int jpeg_quality = 100);

}  // namespace watergs
