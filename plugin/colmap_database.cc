#include "plugin/colmap_database.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

struct CloseDatabase {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};
struct FinalizeStatement {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Statement = std::unique_ptr<sqlite3_stmt, FinalizeStatement>;

Statement Prepare(sqlite3* db, const std::string& path, const char* sql) {
  sqlite3_stmt* statement = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &statement, nullptr) != SQLITE_OK) {
    FailAt(path,
           std::string("not a COLMAP database (") + sqlite3_errmsg(db) + ")");
  }
  return Statement(statement);
}

// sqlite3_step that reads an error as the database's.
bool NextRow(sqlite3* db, sqlite3_stmt* statement, const std::string& path) {
  const int status = sqlite3_step(statement);
  if (status == SQLITE_ROW) return true;
  if (status == SQLITE_DONE) return false;
  FailAt(path, std::string("unreadable database (") + sqlite3_errmsg(db) + ")");
}

using Database = std::unique_ptr<sqlite3, CloseDatabase>;

// `flags`: SQLITE_OPEN_READONLY or SQLITE_OPEN_READWRITE (never creates).
Database Open(const std::string& path, int flags) {
  if (!std::filesystem::is_regular_file(path)) FailAt(path, "no such file");
  sqlite3* raw = nullptr;
  const int opened = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  Database db(raw);
  if (opened != SQLITE_OK) {
    FailAt(path, std::string("cannot open the database (") +
                     (raw ? sqlite3_errmsg(raw) : "out of memory") + ")");
  }
  return db;
}

// Runs one statement that returns no rows.
void Execute(sqlite3* db, const std::string& path, const char* sql) {
  if (sqlite3_exec(db, sql, nullptr, nullptr, nullptr) != SQLITE_OK) {
    FailAt(path, std::string("cannot write the database (") +
                     sqlite3_errmsg(db) + ")");
  }
}

}  // namespace

std::vector<DatabaseImage> ReadDatabaseImages(const std::string& path) {
  const Database db = Open(path, SQLITE_OPEN_READONLY);
  std::map<int, DatabaseImage> images;
  Statement names =
      Prepare(db.get(), path, "SELECT image_id, name FROM images");
  while (NextRow(db.get(), names.get(), path)) {
    DatabaseImage& image = images[sqlite3_column_int(names.get(), 0)];
    image.image_id = sqlite3_column_int(names.get(), 0);
    const unsigned char* name = sqlite3_column_text(names.get(), 1);
    image.name = name ? reinterpret_cast<const char*>(name) : "";
  }
  Statement rows = Prepare(
      db.get(), path, "SELECT image_id, rows, cols, data FROM descriptors");
  while (NextRow(db.get(), rows.get(), path)) {
    const int id = sqlite3_column_int(rows.get(), 0);
    const int64_t count = sqlite3_column_int64(rows.get(), 1);
    const int64_t cols = sqlite3_column_int64(rows.get(), 2);
    const auto* data =
        static_cast<const uint8_t*>(sqlite3_column_blob(rows.get(), 3));
    const int64_t bytes = sqlite3_column_bytes(rows.get(), 3);
    const auto image = images.find(id);
    const std::string which = "descriptors of image_id " + std::to_string(id);
    if (image == images.end()) FailAt(path, which + ": no such image");
    if (count == 0) continue;
    if (cols != 128 || count < 0 || count > (1 << 24) || bytes != count * 128 ||
        !data) {
      FailAt(path, which + " are " + std::to_string(count) + " x " +
                       std::to_string(cols) + " in " + std::to_string(bytes) +
                       " bytes (SIFT: rows x 128 bytes)");
    }
    image->second.descriptors.resize(count, 128);
    std::memcpy(image->second.descriptors.data(), data, size_t(bytes));
  }
  std::vector<DatabaseImage> sorted;
  for (auto& [id, image] : images) sorted.push_back(std::move(image));
  std::sort(sorted.begin(), sorted.end(),
            [](const DatabaseImage& a, const DatabaseImage& b) {
              return a.name < b.name;
            });
  return sorted;
}

SharedCameras ShareCameras(
    const std::string& path,
    const std::vector<std::vector<std::string>>& image_groups) {
  const Database db = Open(path, SQLITE_OPEN_READWRITE);
  // A failure below closes the connection inside the transaction, which
  // SQLite rolls back: the database is changed whole or not at all.
  Execute(db.get(), path, "BEGIN IMMEDIATE");
  Statement camera_of = Prepare(
      db.get(), path,
      "SELECT images.camera_id, cameras.width, cameras.height FROM images "
      "JOIN cameras ON images.camera_id = cameras.camera_id "
      "WHERE images.name = ?");
  Statement assign =
      Prepare(db.get(), path, "UPDATE images SET camera_id = ? WHERE name = ?");
  struct Camera {
    int64_t id, width, height;
  };
  SharedCameras result;
  const auto find_camera = [&](const std::string& name) {
    sqlite3_reset(camera_of.get());
    sqlite3_bind_text(camera_of.get(), 1, name.c_str(), -1, SQLITE_TRANSIENT);
    std::optional<Camera> camera;
    if (NextRow(db.get(), camera_of.get(), path)) {
      camera = Camera{sqlite3_column_int64(camera_of.get(), 0),
                      sqlite3_column_int64(camera_of.get(), 1),
                      sqlite3_column_int64(camera_of.get(), 2)};
    } else {
      result.missing.push_back(name);
    }
    sqlite3_reset(camera_of.get());
    return camera;
  };
  for (const std::vector<std::string>& group : image_groups) {
    std::optional<Camera> shared;
    std::string first;
    for (const std::string& name : group) {
      const std::optional<Camera> own = find_camera(name);
      if (!own) continue;
      if (!shared) {
        shared = own, first = name;
        continue;
      }
      if (own->width != shared->width || own->height != shared->height) {
        FailAt(path, name + "'s camera is " + std::to_string(own->width) + "x" +
                         std::to_string(own->height) + ", " + first + "'s " +
                         std::to_string(shared->width) + "x" +
                         std::to_string(shared->height) +
                         ": photos of two sizes cannot share a camera");
      }
      sqlite3_reset(assign.get());
      sqlite3_bind_int64(assign.get(), 1, shared->id);
      sqlite3_bind_text(assign.get(), 2, name.c_str(), -1, SQLITE_TRANSIENT);
      NextRow(db.get(), assign.get(), path);
    }
  }
  Execute(db.get(), path,
          "DELETE FROM cameras WHERE camera_id NOT IN "
          "(SELECT camera_id FROM images)");
  Statement count = Prepare(db.get(), path, "SELECT COUNT(*) FROM cameras");
  NextRow(db.get(), count.get(), path);
  result.num_cameras = sqlite3_column_int(count.get(), 0);
  camera_of.reset();
  assign.reset();
  count.reset();
  Execute(db.get(), path, "COMMIT");
  return result;
}

}  // namespace watergs
