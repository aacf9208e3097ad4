// Image sizes read from file headers (PNG, JPEG) without decoding, so that a
// workspace can check every image against its camera when it opens.
#pragma once

#include <string>

namespace watergs {

// Fills width/height from a PNG or JPEG header and returns true; returns
// false for other formats or unreadable headers (the caller decodes later).
bool ReadImageHeaderSize(const std::string& path, int* width, int* height);

}  // namespace watergs
