// COLMAP's database.db (SQLite): the images and their SIFT descriptors, which
// watergs matches itself on the CPU (sift_matching.h), and the cameras the
// images share (photo_cameras.h).
#pragma once

#include <string>
#include <vector>

#include "plugin/sift_matching.h"

namespace watergs {

struct DatabaseImage {
  int image_id = 0;
  std::string name;
  // Empty where feature extraction stored none.
  SiftDescriptors descriptors;
};

// Every image of the database at `path` with its descriptors, sorted by name.
// Error (one line naming the file) for a missing or unreadable database, one
// without COLMAP's tables, or descriptors that are not rows x 128 bytes.
std::vector<DatabaseImage> ReadDatabaseImages(const std::string& path);

// What ShareCameras did.
struct SharedCameras {
  // Cameras left in the database.
  int num_cameras = 0;
  // Names of a group the database does not hold (COLMAP's extractor skips a
  // file it cannot read); left out of their group.
  std::vector<std::string> missing;
};

// Gives every image named in a group the camera of the group's first image
// the database holds and deletes the cameras no image uses any more, in one
// transaction. Idempotent. The images of a group must have cameras of one
// size (the caller groups by size): error (one line naming the file, nothing
// changed) for cameras of different sizes.
SharedCameras ShareCameras(
    const std::string& path,
    const std::vector<std::vector<std::string>>& image_groups);

}  // namespace watergs
