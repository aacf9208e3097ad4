// COLMAP 3.8 model files: binary and text readers with full validation, and
// writers that reproduce COLMAP's bytes (record layout, %.17g numbers, header
// comments, unordered_map iteration order).
#include "plugin/reconstruction_io.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {

namespace {

namespace fs = std::filesystem;
static_assert(std::endian::native == std::endian::little,
              "COLMAP .bin files are little-endian; add byte swapping");

// Smallest possible record sizes, used to reject absurd counts before any
// allocation: a count is plausible only if that many minimal records fit in
// the bytes that remain.
constexpr size_t kMinCameraBytes = 4 + 4 + 8 + 8;
constexpr size_t kMinImageBytes = 4 + 4 * 8 + 3 * 8 + 4 + 1 + 8;
constexpr size_t kPoint2DBytes = 8 + 8 + 8;
constexpr size_t kMinPoint3DBytes = 8 + 3 * 8 + 3 + 8 + 8;
constexpr size_t kTrackElementBytes = 4 + 4;

std::string PathIn(const std::string& dir, const std::string& file) {
  return (fs::path(dir) / file).string();
}

bool HasModelFiles(const std::string& dir, const std::string& ext) {
  for (const char* name : {"cameras", "images", "points3D"}) {
    if (!fs::is_regular_file(PathIn(dir, name + ext))) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------
// Validation shared by both formats. `where` names the record.

void CheckFinite(const std::string& path, const std::string& where,
                 const double* values, int count, const char* what) {
  for (int i = 0; i < count; ++i) {
    if (!std::isfinite(values[i])) {
      FailAt(path, where + ": " + what + " is not finite");
    }
  }
}

void CheckCamera(const std::string& path, const std::string& where,
                 const Camera& camera) {
  if (!ExistsCameraModelWithId(camera.model_id)) {
    FailAt(path, where + ": unknown camera model id " +
                     std::to_string(camera.model_id) + " (COLMAP has 0-10)");
  }
  const int expected = CameraModelNumParams(camera.model_id);
  if (static_cast<int>(camera.params.size()) != expected) {
    FailAt(path, where + ": model " + camera.ModelName() + " takes " +
                     std::to_string(expected) + " params (" +
                     CameraModelParamsInfo(camera.model_id) + "), got " +
                     std::to_string(camera.params.size()));
  }
  // Sizes beyond 2^20 pixels a side are corrupt values, and would make
  // per-pixel work (undistortion, int image sizes) blow up.
  constexpr uint64_t kMaxImageSide = uint64_t(1) << 20;
  if (camera.width == 0 || camera.height == 0 || camera.width > kMaxImageSide ||
      camera.height > kMaxImageSide) {
    FailAt(path, where + ": implausible image size " +
                     std::to_string(camera.width) + "x" +
                     std::to_string(camera.height));
  }
  CheckFinite(path, where, camera.params.data(), expected, "a parameter");
  const double fx = camera.FocalLengthX(), fy = camera.FocalLengthY();
  if (fx <= 0 || fy <= 0) FailAt(path, where + ": focal length must be > 0");
}

void AddCheckedCamera(const std::string& path, Camera camera,
                      Reconstruction* reconstruction) {
  const std::string where = "camera " + std::to_string(camera.camera_id);
  CheckCamera(path, where, camera);
  if (!reconstruction->AddCamera(std::move(camera))) {
    FailAt(path, "duplicate " + where);
  }
}

void AddCheckedImage(const std::string& path, Image image,
                     Reconstruction* reconstruction) {
  const std::string where =
      "image " + std::to_string(image.image_id) + " (" + image.name + ")";
  if (image.name.empty()) FailAt(path, where + ": empty name");
  if (!reconstruction->ExistsCamera(image.camera_id)) {
    FailAt(path, where + ": camera " + std::to_string(image.camera_id) +
                     " does not exist in cameras file");
  }
  CheckFinite(path, where, image.qvec.data(), 4, "qvec");
  CheckFinite(path, where, image.tvec.data(), 3, "tvec");
  if (image.qvec.norm() == 0) FailAt(path, where + ": qvec is zero");
  // COLMAP normalizes on reading and again on writing; so do we, to write
  // the same bits.
  image.qvec = NormalizeQuaternion(image.qvec);
  for (const Point2D& point2D : image.points2D) {
    CheckFinite(path, where, point2D.xy.data(), 2, "a point2D");
  }
  const image_t id = image.image_id;
  if (!reconstruction->AddImage(std::move(image))) {
    FailAt(path, "duplicate " + where);
  }
  reconstruction->RegisterImage(id);
}

void AddCheckedPoint3D(const std::string& path, point3D_t id, Point3D point3D,
                       Reconstruction* reconstruction) {
  const std::string where = "point3D " + std::to_string(id);
  CheckFinite(path, where, point3D.xyz.data(), 3, "xyz");
  CheckFinite(path, where, &point3D.error, 1, "error");
  for (const TrackElement& element : point3D.track) {
    if (!reconstruction->ExistsImage(element.image_id)) {
      FailAt(path, where + ": track refers to missing image " +
                       std::to_string(element.image_id));
    }
    const Image& image = reconstruction->GetImage(element.image_id);
    if (element.point2D_idx >= image.points2D.size()) {
      FailAt(path, where + ": track refers to point2D " +
                       std::to_string(element.point2D_idx) + " of image " +
                       std::to_string(element.image_id) + ", which has " +
                       std::to_string(image.points2D.size()));
    }
  }
  if (!reconstruction->AddPoint3D(id, std::move(point3D))) {
    FailAt(path, "duplicate " + where);
  }
}

// ---------------------------------------------------------------------------
// Binary reading.

class BinaryReader {
 public:
  explicit BinaryReader(const std::string& path)
      : path_(path), bytes_(ReadFileBytes(path)) {}
  const std::string& path() const { return path_; }
  size_t Remaining() const { return bytes_.size() - offset_; }

  template <typename T>
  T Read(const std::string& what) {
    if (Remaining() < sizeof(T)) Truncated(what);
    T value;
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  // A record count, refused unless `count` records of at least
  // `min_record_bytes` fit in the rest of the file.
  uint64_t ReadCount(const std::string& what, size_t min_record_bytes) {
    const uint64_t count = Read<uint64_t>("number of " + what);
    if (count > Remaining() / min_record_bytes) {
      FailAt(path_, "claims " + std::to_string(count) + " " + what +
                        " but only " + std::to_string(Remaining()) +
                        " bytes follow (truncated or corrupt file)");
    }
    return count;
  }
  std::string ReadNullTerminated(const std::string& what) {
    const auto begin = bytes_.begin() + offset_;
    const auto end = std::find(begin, bytes_.end(), uint8_t(0));
    if (end == bytes_.end()) Truncated(what);
    std::string text(begin, end);
    offset_ += text.size() + 1;
    return text;
  }
  void ExpectEnd() const {
    if (Remaining() != 0) {
      FailAt(path_, std::to_string(Remaining()) +
                        " unexpected bytes after the last record");
    }
  }

 private:
  [[noreturn]] void Truncated(const std::string& what) const {
    FailAt(path_, "truncated at byte " + std::to_string(offset_) +
                      " while reading " + what);
  }

  std::string path_;
  std::vector<uint8_t> bytes_;
  size_t offset_ = 0;
};

void ReadCamerasBinary(const std::string& path, Reconstruction* out) {
  BinaryReader reader(path);
  const uint64_t num_cameras = reader.ReadCount("cameras", kMinCameraBytes);
  for (uint64_t i = 0; i < num_cameras; ++i) {
    Camera camera;
    camera.camera_id = reader.Read<camera_t>("camera_id");
    camera.model_id = reader.Read<int32_t>("model_id");
    camera.width = reader.Read<uint64_t>("width");
    camera.height = reader.Read<uint64_t>("height");
    if (!ExistsCameraModelWithId(camera.model_id)) {
      CheckCamera(path, "camera " + std::to_string(camera.camera_id), camera);
    }
    camera.params.resize(CameraModelNumParams(camera.model_id));
    for (double& param : camera.params) param = reader.Read<double>("params");
    AddCheckedCamera(path, std::move(camera), out);
  }
  reader.ExpectEnd();
}

void ReadImagesBinary(const std::string& path, Reconstruction* out) {
  BinaryReader reader(path);
  const uint64_t num_images = reader.ReadCount("images", kMinImageBytes);
  for (uint64_t i = 0; i < num_images; ++i) {
    Image image;
    image.image_id = reader.Read<image_t>("image_id");
    for (int k = 0; k < 4; ++k) image.qvec(k) = reader.Read<double>("qvec");
    for (int k = 0; k < 3; ++k) image.tvec(k) = reader.Read<double>("tvec");
    image.camera_id = reader.Read<camera_t>("camera_id");
    image.name = reader.ReadNullTerminated("image name");
    // images.txt cannot hold such a name, and the one-line errors that
    // quote it would break.
    if (image.name.find_first_of("\n\r") != std::string::npos) {
      FailAt(path, "image " + std::to_string(image.image_id) +
                       ": name contains a line break");
    }
    const uint64_t num_points2D = reader.ReadCount(
        "points2D in image " + std::to_string(image.image_id), kPoint2DBytes);
    image.points2D.resize(num_points2D);
    for (Point2D& point2D : image.points2D) {
      point2D.xy(0) = reader.Read<double>("point2D x");
      point2D.xy(1) = reader.Read<double>("point2D y");
      point2D.point3D_id = reader.Read<point3D_t>("point3D_id");
    }
    AddCheckedImage(path, std::move(image), out);
  }
  reader.ExpectEnd();
}

void ReadPoints3DBinary(const std::string& path, Reconstruction* out) {
  BinaryReader reader(path);
  const uint64_t num_points = reader.ReadCount("points3D", kMinPoint3DBytes);
  for (uint64_t i = 0; i < num_points; ++i) {
    Point3D point3D;
    const point3D_t id = reader.Read<point3D_t>("point3D_id");
    for (int k = 0; k < 3; ++k) point3D.xyz(k) = reader.Read<double>("xyz");
    for (int k = 0; k < 3; ++k) point3D.rgb(k) = reader.Read<uint8_t>("rgb");
    point3D.error = reader.Read<double>("error");
    const uint64_t track_length = reader.ReadCount(
        "track elements in point3D " + std::to_string(id), kTrackElementBytes);
    point3D.track.resize(track_length);
    for (TrackElement& element : point3D.track) {
      element.image_id = reader.Read<image_t>("track image_id");
      element.point2D_idx = reader.Read<point2D_t>("track point2D_idx");
    }
    AddCheckedPoint3D(path, id, std::move(point3D), out);
  }
  reader.ExpectEnd();
}

// ---------------------------------------------------------------------------
// Text reading.

class TextReader {
 public:
  explicit TextReader(const std::string& path) : path_(path) {
    const std::vector<uint8_t> bytes = ReadFileBytes(path);
    text_.assign(bytes.begin(), bytes.end());
  }
  const std::string& path() const { return path_; }

  // Next line that is neither empty nor a '#' comment; false at the end.
  bool NextDataLine() {
    while (NextLine()) {
      if (!tokens_.empty() && tokens_[0][0] != '#') return true;
    }
    return false;
  }
  // The very next line, whatever it holds; false at the end.
  bool NextLine() {
    if (offset_ >= text_.size()) return false;
    size_t end = text_.find('\n', offset_);
    if (end == std::string::npos) end = text_.size();
    const std::string_view line(text_.data() + offset_, end - offset_);
    offset_ = end + 1;
    ++line_number_;
    Tokenize(line);
    return true;
  }
  const std::vector<std::string_view>& tokens() const { return tokens_; }

  [[noreturn]] void Fail(const std::string& problem) const {
    FailAt(path_, "line " + std::to_string(line_number_) + ": " + problem);
  }
  double ParseDouble(std::string_view token, const char* what) const {
    double value = 0;
    const auto [end, error] =
        std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc() || end != token.data() + token.size()) {
      Fail(std::string("bad ") + what + " `" + std::string(token) + "`");
    }
    if (!std::isfinite(value)) Fail(std::string(what) + " is not finite");
    return value;
  }
  uint64_t ParseUint(std::string_view token, const char* what,
                     uint64_t max_value) const {
    uint64_t value = 0;
    const auto [end, error] =
        std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc() || end != token.data() + token.size() ||
        value > max_value) {
      Fail(std::string("bad ") + what + " `" + std::string(token) + "`");
    }
    return value;
  }

 private:
  void Tokenize(std::string_view line) {
    tokens_.clear();
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(uint8_t(line[i]))) ++i;
      size_t j = i;
      while (j < line.size() && !std::isspace(uint8_t(line[j]))) ++j;
      if (j > i) tokens_.push_back(line.substr(i, j - i));
      i = j;
    }
  }

  std::string path_;
  std::string text_;
  size_t offset_ = 0;
  int line_number_ = 0;
  std::vector<std::string_view> tokens_;
};

constexpr uint64_t kMaxU32 = std::numeric_limits<uint32_t>::max();
constexpr uint64_t kMaxU64 = std::numeric_limits<uint64_t>::max();

void ReadCamerasText(const std::string& path, Reconstruction* out) {
  TextReader reader(path);
  while (reader.NextDataLine()) {
    const auto& tokens = reader.tokens();
    if (tokens.size() < 4) reader.Fail("expected CAMERA_ID MODEL W H PARAMS");
    Camera camera;
    camera.camera_id = reader.ParseUint(tokens[0], "camera id", kMaxU32);
    camera.model_id = CameraModelNameToId(std::string(tokens[1]));
    if (camera.model_id == kInvalidCameraModelId) {
      reader.Fail("unknown camera model `" + std::string(tokens[1]) + "`");
    }
    camera.width = reader.ParseUint(tokens[2], "width", kMaxU64);
    camera.height = reader.ParseUint(tokens[3], "height", kMaxU64);
    for (size_t i = 4; i < tokens.size(); ++i) {
      camera.params.push_back(reader.ParseDouble(tokens[i], "parameter"));
    }
    AddCheckedCamera(path, std::move(camera), out);
  }
}

// Parses "X Y POINT3D_ID ..." into image->points2D.
void ParsePoints2DLine(const TextReader& reader, Image* image) {
  const auto& tokens = reader.tokens();
  if (tokens.size() % 3 != 0) {
    reader.Fail("POINTS2D must be triples (X, Y, POINT3D_ID)");
  }
  image->points2D.resize(tokens.size() / 3);
  for (size_t i = 0; i < image->points2D.size(); ++i) {
    Point2D& point2D = image->points2D[i];
    point2D.xy(0) = reader.ParseDouble(tokens[3 * i], "point2D x");
    point2D.xy(1) = reader.ParseDouble(tokens[3 * i + 1], "point2D y");
    const std::string_view id = tokens[3 * i + 2];
    point2D.point3D_id = id == "-1"
                             ? kInvalidPoint3DId
                             : reader.ParseUint(id, "point3D id", kMaxU64 - 1);
  }
}

void ReadImagesText(const std::string& path, Reconstruction* out) {
  TextReader reader(path);
  while (reader.NextDataLine()) {
    const auto& tokens = reader.tokens();
    if (tokens.size() < 10) {
      reader.Fail("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    }
    Image image;
    image.image_id = reader.ParseUint(tokens[0], "image id", kMaxU32);
    for (int k = 0; k < 4; ++k) {
      image.qvec(k) = reader.ParseDouble(tokens[1 + k], "qvec");
    }
    for (int k = 0; k < 3; ++k) {
      image.tvec(k) = reader.ParseDouble(tokens[5 + k], "tvec");
    }
    image.camera_id = reader.ParseUint(tokens[8], "camera id", kMaxU32);
    // Names may hold spaces: everything from the 10th field on.
    image.name = std::string(
        tokens[9].data(),
        tokens.back().data() + tokens.back().size() - tokens[9].data());
    if (!reader.NextLine()) {
      reader.Fail("image " + std::to_string(image.image_id) +
                  " lacks its POINTS2D line (truncated file)");
    }
    ParsePoints2DLine(reader, &image);
    AddCheckedImage(path, std::move(image), out);
  }
}

void ReadPoints3DText(const std::string& path, Reconstruction* out) {
  TextReader reader(path);
  while (reader.NextDataLine()) {
    const auto& tokens = reader.tokens();
    if (tokens.size() < 8 || (tokens.size() - 8) % 2 != 0) {
      reader.Fail("expected POINT3D_ID X Y Z R G B ERROR (IMAGE_ID IDX)*");
    }
    Point3D point3D;
    const point3D_t id = reader.ParseUint(tokens[0], "point3D id", kMaxU64 - 1);
    for (int k = 0; k < 3; ++k) {
      point3D.xyz(k) = reader.ParseDouble(tokens[1 + k], "xyz");
      point3D.rgb(k) = reader.ParseUint(tokens[4 + k], "color", 255);
    }
    point3D.error = reader.ParseDouble(tokens[7], "error");
    for (size_t i = 8; i < tokens.size(); i += 2) {
      point3D.track.push_back(
          {static_cast<image_t>(
               reader.ParseUint(tokens[i], "track image id", kMaxU32)),
           static_cast<point2D_t>(
               reader.ParseUint(tokens[i + 1], "track point2D idx", kMaxU32))});
    }
    AddCheckedPoint3D(path, id, std::move(point3D), out);
  }
}

// ---------------------------------------------------------------------------
// Writing.

template <typename T>
void Put(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// COLMAP writes numbers through an ostream with precision 17, i.e. as
// printf's %.17g, which std::to_chars with that precision reproduces
// exactly (and several times faster). Each Append adds a trailing space,
// as COLMAP's writers do before stripping the last one of a line.
void Append(std::string* out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value,
                                    std::chars_format::general, 17);
  out->append(buffer, result.ptr);
  out->push_back(' ');
}
void Append(std::string* out, uint64_t value) {
  char buffer[24];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
  out->push_back(' ');
}
void Append(std::string* out, const std::string& text) {
  out->append(text);
  out->push_back(' ');
}
// Ends a line: the trailing space becomes the newline.
void EndLine(std::string* out) {
  if (!out->empty() && out->back() == ' ') out->pop_back();
  out->push_back('\n');
}
// A header number (no trailing space).
std::string Number(double value) {
  std::string text;
  Append(&text, value);
  text.pop_back();
  return text;
}

}  // namespace

std::string FindModelPath(const std::string& path) {
  for (const std::string& candidate :
       {path, PathIn(path, "sparse/0"), PathIn(path, "sparse")}) {
    if (fs::is_regular_file(PathIn(candidate, "cameras.bin")) ||
        fs::is_regular_file(PathIn(candidate, "cameras.txt"))) {
      return candidate;
    }
  }
  if (!fs::exists(path)) FailAt(path, "no such folder");
  FailAt(path,
         "no COLMAP model here (looked for cameras.bin/.txt in it, in "
         "sparse/0 and in sparse)");
}

ModelFormat DetectModelFormat(const std::string& model_path) {
  if (HasModelFiles(model_path, ".bin")) return ModelFormat::kBinary;
  if (HasModelFiles(model_path, ".txt")) return ModelFormat::kText;
  // A partial model: name the first missing file of the format begun.
  for (const char* ext : {".bin", ".txt"}) {
    if (!fs::is_regular_file(
            PathIn(model_path, "cameras" + std::string(ext)))) {
      continue;
    }
    for (const char* name : {"images", "points3D"}) {
      const std::string file = PathIn(model_path, name + std::string(ext));
      if (!fs::is_regular_file(file)) {
        FailAt(file, "missing (a model needs cameras, images and points3D)");
      }
    }
  }
  FailAt(model_path, "no cameras/images/points3D .bin or .txt files");
}

namespace {

// Every observed point3D must be in the points3D file: a file cut at a line
// (or record) boundary otherwise reads as a smaller, valid-looking model.
void CheckObservedPointsExist(const std::string& points3D_path,
                              const Reconstruction& reconstruction) {
  for (const auto& [image_id, image] : reconstruction.Images()) {
    for (const Point2D& point2D : image.points2D) {
      if (point2D.point3D_id != kInvalidPoint3DId &&
          !reconstruction.ExistsPoint3D(point2D.point3D_id)) {
        FailAt(points3D_path, "lacks point3D " +
                                  std::to_string(point2D.point3D_id) +
                                  ", which image " + std::to_string(image_id) +
                                  " observes (truncated file?)");
      }
    }
  }
}

}  // namespace

Reconstruction ReadReconstruction(const std::string& path) {
  const std::string model_path = FindModelPath(path);
  return DetectModelFormat(model_path) == ModelFormat::kBinary
             ? ReadReconstructionBinary(model_path)
             : ReadReconstructionText(model_path);
}

Reconstruction ReadReconstructionBinary(const std::string& model_path) {
  Reconstruction reconstruction;
  ReadCamerasBinary(PathIn(model_path, "cameras.bin"), &reconstruction);
  ReadImagesBinary(PathIn(model_path, "images.bin"), &reconstruction);
  ReadPoints3DBinary(PathIn(model_path, "points3D.bin"), &reconstruction);
  CheckObservedPointsExist(PathIn(model_path, "points3D.bin"), reconstruction);
  return reconstruction;
}

Reconstruction ReadReconstructionText(const std::string& model_path) {
  Reconstruction reconstruction;
  ReadCamerasText(PathIn(model_path, "cameras.txt"), &reconstruction);
  ReadImagesText(PathIn(model_path, "images.txt"), &reconstruction);
  ReadPoints3DText(PathIn(model_path, "points3D.txt"), &reconstruction);
  CheckObservedPointsExist(PathIn(model_path, "points3D.txt"), reconstruction);
  return reconstruction;
}

std::string CamerasText(const Reconstruction& reconstruction) {
  std::string file =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: " +
      std::to_string(reconstruction.NumCameras()) + "\n";
  for (const auto& [id, camera] : reconstruction.Cameras()) {
    Append(&file, uint64_t(id));
    Append(&file, camera.ModelName());
    Append(&file, camera.width);
    Append(&file, camera.height);
    for (const double param : camera.params) Append(&file, param);
    EndLine(&file);
  }
  return file;
}

std::string ImagesText(const Reconstruction& reconstruction) {
  std::string file =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Number of images: " +
      std::to_string(reconstruction.NumRegImages()) +
      ", mean observations per image: " +
      Number(reconstruction.ComputeMeanObservationsPerRegImage()) + "\n";
  for (const auto& [id, image] : reconstruction.Images()) {
    if (!reconstruction.IsImageRegistered(id)) continue;
    Append(&file, uint64_t(id));
    const Eigen::Vector4d qvec = NormalizeQuaternion(image.qvec);
    for (int k = 0; k < 4; ++k) Append(&file, qvec(k));
    for (int k = 0; k < 3; ++k) Append(&file, image.tvec(k));
    Append(&file, uint64_t(image.camera_id));
    file += image.name + "\n";
    for (const Point2D& point2D : image.points2D) {
      Append(&file, point2D.xy(0));
      Append(&file, point2D.xy(1));
      if (point2D.HasPoint3D()) {
        Append(&file, point2D.point3D_id);
      } else {
        file += "-1 ";
      }
    }
    EndLine(&file);
  }
  return file;
}

std::string Points3DText(const Reconstruction& reconstruction) {
  std::string file =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as "
      "(IMAGE_ID, POINT2D_IDX)\n"
      "# Number of points: " +
      std::to_string(reconstruction.NumPoints3D()) + ", mean track length: " +
      Number(reconstruction.ComputeMeanTrackLength()) + "\n";
  for (const auto& [id, point3D] : reconstruction.Points3D()) {
    Append(&file, id);
    for (int k = 0; k < 3; ++k) Append(&file, point3D.xyz(k));
    for (int k = 0; k < 3; ++k) Append(&file, uint64_t(point3D.rgb(k)));
    Append(&file, point3D.error);
    for (const TrackElement& element : point3D.track) {
      Append(&file, uint64_t(element.image_id));
      Append(&file, uint64_t(element.point2D_idx));
    }
    // COLMAP strips the last space of the track part only: an empty track
    // leaves the space after ERROR in place.
    if (point3D.track.empty()) {
      file.push_back('\n');
    } else {
      EndLine(&file);
    }
  }
  return file;
}

std::string CamerasBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.NumCameras());
  for (const auto& [id, camera] : reconstruction.Cameras()) {
    Put<camera_t>(&out, id);
    Put<int32_t>(&out, camera.model_id);
    Put<uint64_t>(&out, camera.width);
    Put<uint64_t>(&out, camera.height);
    for (const double param : camera.params) Put<double>(&out, param);
  }
  return out;
}

std::string ImagesBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.NumRegImages());
  for (const auto& [id, image] : reconstruction.Images()) {
    if (!reconstruction.IsImageRegistered(id)) continue;
    Put<image_t>(&out, id);
    const Eigen::Vector4d qvec = NormalizeQuaternion(image.qvec);
    for (int k = 0; k < 4; ++k) Put<double>(&out, qvec(k));
    for (int k = 0; k < 3; ++k) Put<double>(&out, image.tvec(k));
    Put<camera_t>(&out, image.camera_id);
    out.append(image.name);
    out.push_back('\0');
    Put<uint64_t>(&out, image.points2D.size());
    for (const Point2D& point2D : image.points2D) {
      Put<double>(&out, point2D.xy(0));
      Put<double>(&out, point2D.xy(1));
      Put<point3D_t>(&out, point2D.point3D_id);
    }
  }
  return out;
}

std::string Points3DBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.NumPoints3D());
  for (const auto& [id, point3D] : reconstruction.Points3D()) {
    Put<point3D_t>(&out, id);
    for (int k = 0; k < 3; ++k) Put<double>(&out, point3D.xyz(k));
    for (int k = 0; k < 3; ++k) Put<uint8_t>(&out, point3D.rgb(k));
    Put<double>(&out, point3D.error);
    Put<uint64_t>(&out, point3D.track.size());
    for (const TrackElement& element : point3D.track) {
      Put<image_t>(&out, element.image_id);
      Put<point2D_t>(&out, element.point2D_idx);
    }
  }
  return out;
}

void WriteReconstruction(const Reconstruction& reconstruction,
                         const std::string& model_path, ModelFormat format) {
  CreateDirectories(model_path);
  // As a set: a failure on points3D must not leave new cameras and images
  // beside an old points3D (a model that reads but is wrong).
  if (format == ModelFormat::kBinary) {
    AtomicWriteFiles(
        {{PathIn(model_path, "cameras.bin"), CamerasBinary(reconstruction)},
         {PathIn(model_path, "images.bin"), ImagesBinary(reconstruction)},
         {PathIn(model_path, "points3D.bin"), Points3DBinary(reconstruction)}});
  } else {
    AtomicWriteFiles(
        {{PathIn(model_path, "cameras.txt"), CamerasText(reconstruction)},
         {PathIn(model_path, "images.txt"), ImagesText(reconstruction)},
         {PathIn(model_path, "points3D.txt"), Points3DText(reconstruction)}});
  }
}

ModelFormat ParseModelFormat(const std::string& name) {
  std::string upper = name;
  std::transform(upper.begin(), upper.end(), upper.begin(), ::toupper);
  if (upper == "BIN") return ModelFormat::kBinary;
  if (upper == "TXT") return ModelFormat::kText;
  Fail("unknown model format `" + name + "` (expected BIN or TXT)");
}

}  // namespace watergs
