#include "plugin/suspect_reference.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <vector>

#include "watermark/image_attacks.h"

namespace watergs {
namespace {

// The JPEG standard's luminance quantisation table (Annex K), natural order.
constexpr std::array<int, 64> kLuminance = {
    16, 11, 10, 16, 24,  40,  51,  61,  12, 12, 14, 19, 26,  58,  60,  55,
    14, 13, 16, 24, 40,  57,  69,  56,  14, 17, 22, 29, 51,  87,  80,  62,
    18, 22, 37, 56, 68,  109, 103, 77,  24, 35, 55, 64, 81,  104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99};

// Natural position of the k-th coefficient in zigzag order (DQT's order).
constexpr std::array<int, 64> kZigzag = {
    0,  1,  8,  16, 9,  2,  3,  10, 17, 24, 32, 25, 18, 11, 4,  5,
    12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6,  7,  14, 21, 28,
    35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51,
    58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63};

// libjpeg's jpeg_quality_scaling and jpeg_add_quant_table (baseline).
int ScaledEntry(int base, int quality) {
  const int scale = quality < 50 ? 5000 / quality : 200 - 2 * quality;
  return std::clamp((base * scale + 50) / 100, 1, 255);
}

// Table 0 of the first DQT marker, natural order; empty if none.
std::vector<int> LuminanceTable(const std::vector<uint8_t>& bytes) {
  if (bytes.size() < 4 || bytes[0] != 0xFF || bytes[1] != 0xD8) return {};
  size_t at = 2;
  while (at + 4 <= bytes.size() && bytes[at] == 0xFF) {
    const int marker = bytes[at + 1];
    const size_t length = size_t(bytes[at + 2]) << 8 | bytes[at + 3];
    if (length < 2 || at + 2 + length > bytes.size()) return {};
    if (marker == 0xDA) return {};  // scan data: no table before it
    if (marker == 0xDB) {
      size_t p = at + 4;
      const size_t end = at + 2 + length;
      while (p < end) {
        const int precision = bytes[p] >> 4, id = bytes[p] & 15;
        const size_t size = precision ? 128 : 64;
        if (p + 1 + size > end) return {};
        if (id == 0) {
          std::vector<int> table(64);
          for (int k = 0; k < 64; ++k) {
            table[size_t(kZigzag[size_t(k)])] =
                precision ? bytes[p + 1 + 2 * k] << 8 | bytes[p + 2 + 2 * k]
                          : bytes[p + 1 + k];
          }
          return table;
        }
        p += 1 + size;
      }
    }
    at += 2 + length;
  }
  return {};
}

}  // namespace

int JpegQualityOf(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  // The tables come before the scan; 64 KiB holds any header.
  std::vector<uint8_t> bytes(65536);
  file.read(reinterpret_cast<char*>(bytes.data()),
            std::streamsize(bytes.size()));
  bytes.resize(size_t(file.gcount()));
  const std::vector<int> table = LuminanceTable(bytes);
  if (table.empty()) return 0;
  for (int quality = 1; quality <= 100; ++quality) {
    bool same = true;
    for (size_t i = 0; i < 64 && same; ++i) {
      same = table[i] == ScaledEntry(kLuminance[i], quality);
    }
    if (same) return quality;
  }
  return 0;
}

ImageRGB RenderLikeSuspect(const CameraRenderer& render,
                           const RenderCamera& camera,
                           const SuspectProcessing& processing) {
  RenderCamera at_file = camera;
  const bool resized =
      processing.width > 0 && processing.height > 0 &&
      (processing.width != camera.width || processing.height != camera.height);
  if (resized) {
    // Pixel coordinates scale with the image (their origin is its corner).
    const double sx = double(processing.width) / camera.width;
    const double sy = double(processing.height) / camera.height;
    at_file.width = processing.width;
    at_file.height = processing.height;
    at_file.fx *= sx;
    at_file.cx *= sx;
    at_file.fy *= sy;
    at_file.cy *= sy;
  }
  ImageRGB image = render(at_file);
  if (processing.jpeg_quality > 0) {
    image = ApplyImageAttack(
        {ImageAttackKind::kJpeg, double(processing.jpeg_quality)}, image);
  }
  return resized ? ResizeTo(image, camera.width, camera.height) : image;
}

}  // namespace watergs
