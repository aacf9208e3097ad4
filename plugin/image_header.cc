// PNG (IHDR) and JPEG (SOFn marker) header parsing for image sizes.
#include "plugin/image_header.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

namespace watergs {

namespace {

uint32_t BigEndian(const uint8_t* bytes, int count) {
  uint32_t value = 0;
  for (int i = 0; i < count; ++i) value = (value << 8) | bytes[i];
  return value;
}

bool PngSize(std::ifstream& file, int* width, int* height) {
  uint8_t header[24];
  file.seekg(0);
  if (!file.read(reinterpret_cast<char*>(header), sizeof(header))) return false;
  if (std::memcmp(header + 12, "IHDR", 4) != 0) return false;
  *width = BigEndian(header + 16, 4);
  *height = BigEndian(header + 20, 4);
  return true;
}

// Walks the marker segments up to the first start-of-frame (SOF0-SOF15 but
// DHT C4, JPG C8 and DAC CC), whose payload holds height then width.
bool JpegSize(std::ifstream& file, int* width, int* height) {
  file.seekg(2);
  uint8_t marker[4];
  while (file.read(reinterpret_cast<char*>(marker), 2)) {
    if (marker[0] != 0xFF) return false;
    if (marker[1] == 0xFF) {
      file.seekg(-1, std::ios::cur);
      continue;
    }
    const uint8_t type = marker[1];
    if (type == 0xD8 || (type >= 0xD0 && type <= 0xD7) || type == 0x01) {
      continue;
    }
    if (!file.read(reinterpret_cast<char*>(marker + 2), 2)) return false;
    const uint32_t length = BigEndian(marker + 2, 2);
    if (length < 2) return false;
    const bool sof = type >= 0xC0 && type <= 0xCF && type != 0xC4 &&
                     type != 0xC8 && type != 0xCC;
    if (sof) {
      uint8_t frame[5];
      if (!file.read(reinterpret_cast<char*>(frame), 5)) return false;
      *height = BigEndian(frame + 1, 2);
      *width = BigEndian(frame + 3, 2);
      return *width > 0 && *height > 0;
    }
    file.seekg(length - 2, std::ios::cur);
  }
  return false;
}

}  // namespace

bool ReadImageHeaderSize(const std::string& path, int* width, int* height) {
  std::ifstream file(path, std::ios::binary);
  uint8_t magic[8] = {0};
  if (!file.read(reinterpret_cast<char*>(magic), 8)) return false;
  static const uint8_t kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (std::memcmp(magic, kPng, 8) == 0) return PngSize(file, width, height);
  if (magic[0] == 0xFF && magic[1] == 0xD8) {
    return JpegSize(file, width, height);
  }
  return false;
}

}  // namespace watergs
