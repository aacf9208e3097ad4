// Reading COLMAP's database.db (SQLite): the images and their SIFT
// descriptors, which watergs matches itself on the CPU (sift_matching.h).
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

}  // namespace watergs
