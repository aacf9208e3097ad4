// Which photos of a folder come from one camera, for reconstruct: the EXIF
// make, model and focal length with the pixel size. Photos of one camera share
// one set of intrinsics in the model (one focal length, refined on every photo
// of that camera, not one per photo); photos of another camera, or of another
// size, get their own.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace watergs {

// The camera a photo's EXIF names.
struct ExifCamera {
  std::string make, model;
  // The lens's focal length (EXIF FocalLength); 0 where not recorded.
  double focal_length_mm = 0;

  // "Canon EOS 5D 24 mm" (make, model, focal length where known).
  std::string Label() const;
};

// The EXIF camera of the photo at `path`; nullopt where the file records no
// make or model (PNGs, stripped or garbage EXIF). Reads the file's EXIF only
// (libexif), never throws.
std::optional<ExifCamera> ReadExifCamera(const std::string& path);

// One photo as the grouping sees it.
struct PhotoDescription {
  int width = 0, height = 0;
  std::optional<ExifCamera> exif;
};

// Photos assigned to cameras; `group[k]` is photo k's camera (0-based).
struct PhotoCameras {
  std::vector<int> group;
  int num_groups = 0;
  // Cameras named by an EXIF camera and size, and photos that name none.
  int num_exif_cameras = 0;
  int num_without_exif = 0;
  bool one_size = true;
  // One line: "22 of Canon EOS 5D 24 mm 480x360, 2 of ...".
  std::string summary;
};

// Photos in capture order of one size and at most one EXIF camera share one
// camera (a walk or a video); otherwise photos of the same EXIF camera (make,
// model, focal length) and size share a camera and each photo without one
// (no EXIF, or no focal length: a zoom's settings unknown) gets its own (a web
// collection's photos come from many cameras).
PhotoCameras GroupPhotosByCamera(const std::vector<PhotoDescription>& photos,
                                 bool in_capture_order);

}  // namespace watergs
