// EXIF cameras through libexif, and the grouping of photos by camera and size.
#include "plugin/photo_cameras.h"

#include <libexif/exif-data.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <tuple>

namespace watergs {
namespace {

struct UnrefExifData {
  void operator()(ExifData* data) const { exif_data_unref(data); }
};

// An ASCII tag's text without the padding cameras leave (spaces, NULs).
std::string AsciiTag(ExifData* data, ExifIfd ifd, ExifTag tag) {
  ExifEntry* entry = exif_content_get_entry(data->ifd[ifd], tag);
  if (!entry || entry->format != EXIF_FORMAT_ASCII || !entry->data) return "";
  std::string text(reinterpret_cast<const char*>(entry->data), entry->size);
  text = text.substr(0, text.find('\0'));
  const size_t first = text.find_first_not_of(' ');
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(' ') - first + 1);
}

double FocalLengthMm(ExifData* data) {
  ExifEntry* entry =
      exif_content_get_entry(data->ifd[EXIF_IFD_EXIF], EXIF_TAG_FOCAL_LENGTH);
  if (!entry || entry->format != EXIF_FORMAT_RATIONAL ||
      entry->components < 1 || !entry->data || entry->size < 8) {
    return 0;
  }
  const ExifRational r =
      exif_get_rational(entry->data, exif_data_get_byte_order(data));
  if (r.denominator == 0) return 0;
  const double mm = double(r.numerator) / r.denominator;
  return std::isfinite(mm) && mm > 0 && mm < 1e4 ? mm : 0;
}

}  // namespace

std::string ExifCamera::Label() const {
  std::string label = make;
  // Most cameras repeat the make in the model ("Canon" "Canon EOS 5D").
  if (model.rfind(make, 0) == 0) {
    label = model;
  } else if (!model.empty()) {
    label += (label.empty() ? "" : " ") + model;
  }
  if (focal_length_mm > 0) {
    char focal[32];
    std::snprintf(focal, sizeof(focal), " %g mm", focal_length_mm);
    label += focal;
  }
  return label;
}

std::optional<ExifCamera> ReadExifCamera(const std::string& path) {
  std::unique_ptr<ExifData, UnrefExifData> data(
      exif_data_new_from_file(path.c_str()));
  if (!data) return std::nullopt;
  ExifCamera camera;
  camera.make = AsciiTag(data.get(), EXIF_IFD_0, EXIF_TAG_MAKE);
  camera.model = AsciiTag(data.get(), EXIF_IFD_0, EXIF_TAG_MODEL);
  if (camera.make.empty() && camera.model.empty()) return std::nullopt;
  camera.focal_length_mm = FocalLengthMm(data.get());
  return camera;
}

PhotoCameras GroupPhotosByCamera(const std::vector<PhotoDescription>& photos,
                                 bool in_capture_order) {
  PhotoCameras cameras;
  cameras.group.assign(photos.size(), 0);
  using Key = std::tuple<std::string, std::string, double, int, int>;
  std::map<Key, int> exif_group;
  std::map<int, int> photos_in_group;
  for (size_t k = 0; k < photos.size(); ++k) {
    const PhotoDescription& p = photos[k];
    cameras.one_size = cameras.one_size && p.width == photos[0].width &&
                       p.height == photos[0].height;
    // Without a focal length a zoom's settings cannot be told apart.
    if (!p.exif || p.exif->focal_length_mm <= 0) {
      ++cameras.num_without_exif;
      cameras.group[k] = -1;
      continue;
    }
    const Key key{p.exif->make, p.exif->model, p.exif->focal_length_mm, p.width,
                  p.height};
    const auto found = exif_group.emplace(key, int(exif_group.size()));
    cameras.group[k] = found.first->second;
    ++photos_in_group[found.first->second];
  }
  cameras.num_exif_cameras = int(exif_group.size());
  if (in_capture_order && cameras.one_size && cameras.num_exif_cameras <= 1) {
    std::fill(cameras.group.begin(), cameras.group.end(), 0);
    cameras.num_groups = photos.empty() ? 0 : 1;
    cameras.summary =
        std::to_string(photos.size()) + " photos in capture " +
        "order, one size" +
        (cameras.num_exif_cameras == 1 ? ", one EXIF camera" : "");
    return cameras;
  }
  // Photos without an EXIF camera: a camera each, after the EXIF cameras.
  cameras.num_groups = cameras.num_exif_cameras;
  for (int& g : cameras.group) {
    if (g < 0) g = cameras.num_groups++;
  }
  // The summary names the EXIF cameras with the most photos first.
  std::vector<std::pair<int, const Key*>> named;
  for (const auto& [key, g] : exif_group) {
    named.emplace_back(photos_in_group[g], &key);
  }
  std::stable_sort(
      named.begin(), named.end(),
      [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string summary;
  for (size_t k = 0; k < named.size() && k < 3; ++k) {
    const auto& [make, model, focal, w, h] = *named[k].second;
    summary += (summary.empty() ? "" : ", ") + std::to_string(named[k].first) +
               " of " + ExifCamera{make, model, focal}.Label() + " " +
               std::to_string(w) + "x" + std::to_string(h);
  }
  if (named.size() > 3) {
    summary +=
        " and " + std::to_string(named.size() - 3) + " EXIF camera(s) more";
  }
  if (cameras.num_without_exif > 0) {
    summary += (summary.empty() ? "" : "; ") +
               std::to_string(cameras.num_without_exif) +
               " photo(s) without an EXIF camera, a camera each";
  }
  cameras.summary = summary;
  return cameras;
}

}  // namespace watergs
