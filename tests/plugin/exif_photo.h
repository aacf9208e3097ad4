// Test helper: JPEG photos whose EXIF names a camera (make, model, focal
// length), written with libexif, to stand for photos of different cameras.
#pragma once

#include <libexif/exif-data.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <utility>
#include <vector>

namespace watergs::testing {

// Adds an entry of `format` with `size` bytes of data (zeroed) to `ifd`.
inline ExifEntry* AddExifEntry(ExifData* data, ExifIfd ifd, ExifTag tag,
                               ExifFormat format, unsigned components,
                               unsigned size) {
  ExifEntry* entry = exif_entry_new();
  entry->tag = tag;
  entry->format = format;
  entry->components = components;
  entry->size = size;
  // libexif's default allocator frees with free().
  entry->data = static_cast<unsigned char*>(std::calloc(size, 1));
  exif_content_add_entry(data->ifd[ifd], entry);
  exif_entry_unref(entry);
  return entry;
}

// The APP1 payload ("Exif\0\0" and a TIFF block) naming the camera.
inline std::vector<unsigned char> ExifCameraBlock(const std::string& make,
                                                  const std::string& model,
                                                  double focal_length_mm) {
  ExifData* data = exif_data_new();
  exif_data_unset_option(data, EXIF_DATA_OPTION_FOLLOW_SPECIFICATION);
  exif_data_set_byte_order(data, EXIF_BYTE_ORDER_INTEL);
  const std::pair<ExifTag, std::string> texts[] = {{EXIF_TAG_MAKE, make},
                                                   {EXIF_TAG_MODEL, model}};
  for (const auto& [tag, text] : texts) {
    ExifEntry* e = AddExifEntry(data, EXIF_IFD_0, tag, EXIF_FORMAT_ASCII,
                                text.size() + 1, text.size() + 1);
    std::memcpy(e->data, text.c_str(), text.size() + 1);
  }
  if (focal_length_mm > 0) {
    ExifEntry* e = AddExifEntry(data, EXIF_IFD_EXIF, EXIF_TAG_FOCAL_LENGTH,
                                EXIF_FORMAT_RATIONAL, 1, 8);
    exif_set_rational(e->data, EXIF_BYTE_ORDER_INTEL,
                      {ExifLong(focal_length_mm * 100 + 0.5), 100});
  }
  unsigned char* bytes = nullptr;
  unsigned int size = 0;
  exif_data_save_data(data, &bytes, &size);
  std::vector<unsigned char> block(bytes, bytes + size);
  std::free(bytes);
  exif_data_unref(data);
  return block;
}

// `image` as a JPEG (quality 95) with an APP1 segment holding `exif_block`
// right after its start marker; no EXIF where the block is empty.
inline bool WriteJpegWithExif(const std::string& path, const cv::Mat& image,
                              const std::vector<unsigned char>& exif_block) {
  std::vector<unsigned char> jpeg;
  if (!cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95})) {
    return false;
  }
  if (!exif_block.empty()) {
    const size_t length = exif_block.size() + 2;
    std::vector<unsigned char> segment = {
        0xFF, 0xE1, static_cast<unsigned char>(length >> 8),
        static_cast<unsigned char>(length & 0xFF)};
    segment.insert(segment.end(), exif_block.begin(), exif_block.end());
    jpeg.insert(jpeg.begin() + 2, segment.begin(), segment.end());
  }
  FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) return false;
  const bool written =
      std::fwrite(jpeg.data(), 1, jpeg.size(), file) == jpeg.size();
  return std::fclose(file) == 0 && written;
}

}  // namespace watergs::testing
