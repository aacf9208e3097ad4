// PlayCanvas SOG reader and writer (see sog_io.h): libzip for the bundle,
// libwebp for the images, nlohmann::json for meta.json.
#include "gaussian/formats/sog_io.h"

#include <webp/decode.h>
#include <webp/encode.h>
#include <zip.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <utility>

#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/formats/kmeans.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"

namespace watergs {
namespace {

using nlohmann::json;

// More Gaussians than any published scene; refused before any allocation.
constexpr size_t kMaxSogCount = size_t(1) << 27;
// A meta.json is a few KB (three 256-entry codebooks).
constexpr size_t kMaxMetaBytes = size_t(16) << 20;
// Largest ZIP member read (a WebP of 2^27 pixels is well under this).
constexpr size_t kMaxMemberBytes = size_t(1) << 30;
constexpr int kCodebookSize = 256;
constexpr size_t kPaletteRow = 64;  // palette entries per centroids row

struct Rgba {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;  // width * height * 4
  const uint8_t* at(size_t i) const { return &pixels[4 * i]; }
};

// Pixels an image may hold for `needed` of them: splat-transform pads to a
// multiple of 4 in each direction; anything far larger is refused before
// decoding (a 16383 x 16383 WebP header would ask for 1 GB).
size_t PixelBudget(size_t needed) { return 2 * needed + 65536; }

Rgba DecodeWebp(const std::string& where, const std::string& bytes,
                size_t needed) {
  const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
  Rgba image;
  if (!WebPGetInfo(data, bytes.size(), &image.width, &image.height)) {
    FailAt(where, "not a WebP image (or its header is truncated)");
  }
  WebPBitstreamFeatures features;
  if (WebPGetFeatures(data, bytes.size(), &features) == VP8_STATUS_OK &&
      features.format == 1) {
    FailAt(where,
           "a lossy WebP: SOG images must be lossless (their bytes "
           "are indices and fixed-point values)");
  }
  const size_t pixels = size_t(image.width) * size_t(image.height);
  if (pixels < needed) {
    FailAt(where,
           std::to_string(image.width) + "x" + std::to_string(image.height) +
               " pixels, fewer than the " + std::to_string(needed) + " needed");
  }
  if (pixels > PixelBudget(needed)) {
    FailAt(where, std::to_string(image.width) + "x" +
                      std::to_string(image.height) + " pixels for " +
                      std::to_string(needed) + " values: absurd size");
  }
  image.pixels.resize(4 * pixels);
  if (!WebPDecodeRGBAInto(data, bytes.size(), image.pixels.data(),
                          image.pixels.size(), 4 * image.width)) {
    FailAt(where, "corrupt or truncated WebP data");
  }
  return image;
}

std::string EncodeWebpLossless(const std::vector<uint8_t>& rgba, int width,
                               int height, int method) {
  WebPConfig config;
  WebPPicture picture;
  if (!WebPConfigInit(&config) || !WebPPictureInit(&picture)) {
    Fail("SOG: libwebp version mismatch");
  }
  config.lossless = 1;
  config.method = std::clamp(method, 0, 6);
  config.quality = method == 0 ? 0.f : 75.f;  // lossless: effort, not loss
  config.exact = 1;  // keep the bytes under alpha 0 (they are indices)
  picture.use_argb = 1;
  picture.width = width;
  picture.height = height;
  WebPMemoryWriter writer;
  WebPMemoryWriterInit(&writer);
  picture.writer = WebPMemoryWrite;
  picture.custom_ptr = &writer;
  const bool ok = WebPPictureImportRGBA(&picture, rgba.data(), 4 * width) &&
                  WebPEncode(&config, &picture);
  WebPPictureFree(&picture);
  std::string out(reinterpret_cast<const char*>(writer.mem), writer.size);
  WebPMemoryWriterClear(&writer);
  if (!ok) Fail("SOG: WebP encoding failed");
  return out;
}

// Read access to the members of a ZIP held in memory.
class ZipArchive {
 public:
  ZipArchive(std::string name, const uint8_t* data, size_t size)
      : name_(std::move(name)) {
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* source = zip_source_buffer_create(data, size, 0, &error);
    if (source != nullptr) {
      archive_ = zip_open_from_source(source, ZIP_RDONLY, &error);
      if (archive_ == nullptr) zip_source_free(source);
    }
    if (archive_ == nullptr) {
      const std::string why = zip_error_strerror(&error);
      zip_error_fini(&error);
      FailAt(name_, "not a readable ZIP archive (" + Printable(why) + ")");
    }
    zip_error_fini(&error);
  }
  ~ZipArchive() { zip_discard(archive_); }
  ZipArchive(const ZipArchive&) = delete;
  ZipArchive& operator=(const ZipArchive&) = delete;

  // The bytes of `member`; Error if it is missing, corrupt or > limit.
  std::string Read(const std::string& member, size_t limit) const {
    const std::string where = name_ + ": " + Printable(member);
    const zip_int64_t index = zip_name_locate(archive_, member.c_str(), 0);
    if (index < 0) Fail(where + ": not in the archive");
    zip_file_t* file = zip_fopen_index(archive_, zip_uint64_t(index), 0);
    if (file == nullptr) {
      Fail(where + ": cannot open (" + Printable(zip_strerror(archive_)) + ")");
    }
    std::string bytes;
    zip_stat_t stat;
    if (zip_stat_index(archive_, zip_uint64_t(index), 0, &stat) == 0 &&
        (stat.valid & ZIP_STAT_SIZE) && stat.size <= limit) {
      bytes.reserve(size_t(stat.size));  // no doubling peak
    }
    char buffer[1 << 16];
    zip_int64_t got = 0;
    while ((got = zip_fread(file, buffer, sizeof buffer)) > 0) {
      bytes.append(buffer, size_t(got));
      if (bytes.size() > limit) {
        zip_fclose(file);
        Fail(where + ": larger than " + std::to_string(limit) + " bytes");
      }
    }
    const std::string why = got < 0 ? zip_file_strerror(file) : "";
    zip_fclose(file);
    if (got < 0)
      Fail(where + ": corrupt or truncated (" + Printable(why) + ")");
    return bytes;
  }

 private:
  std::string name_;
  zip_t* archive_ = nullptr;
};

// A ZIP of (name, bytes) members, stored: WebP is compressed already.
std::string ZipStore(
    const std::vector<std::pair<std::string, std::string>>& members) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* out = zip_source_buffer_create(nullptr, 0, 0, &error);
  if (out == nullptr) Fail("SOG: cannot create a ZIP buffer");
  zip_t* archive = zip_open_from_source(out, ZIP_TRUNCATE, &error);
  zip_error_fini(&error);
  if (archive == nullptr) {
    zip_source_free(out);
    Fail("SOG: writing the ZIP failed: cannot open");
  }
  // The archive owns `out` now; one more reference keeps it past zip_close.
  zip_source_keep(out);
  auto fail = [&](const std::string& why) {
    if (archive != nullptr) zip_discard(archive);
    zip_source_free(out);
    Fail("SOG: writing the ZIP failed: " + why);
  };
  for (const auto& [name, bytes] : members) {
    zip_source_t* member =
        zip_source_buffer(archive, bytes.data(), bytes.size(), 0);
    const zip_int64_t index =
        member == nullptr
            ? -1
            : zip_file_add(archive, name.c_str(), member, ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      if (member != nullptr) zip_source_free(member);
      fail(zip_strerror(archive));
    }
    // A fixed DOS time stamp (1980-01-01 00:00, no time zone involved): the
    // same model gives the same bytes.
    zip_set_file_compression(archive, zip_uint64_t(index), ZIP_CM_STORE, 0);
    zip_file_set_dostime(archive, zip_uint64_t(index), 0, 0x21, 0);
  }
  if (zip_close(archive) < 0) fail(zip_strerror(archive));  // still ours
  archive = nullptr;
  std::string bytes;
  if (zip_source_open(out) < 0) fail("cannot reopen the buffer");
  zip_source_seek(out, 0, SEEK_END);
  const zip_int64_t size = zip_source_tell(out);
  if (size < 0) {
    zip_source_close(out);
    fail("cannot size the buffer");
  }
  bytes.resize(size_t(size));
  zip_source_seek(out, 0, SEEK_SET);
  const zip_int64_t got = zip_source_read(out, bytes.data(), bytes.size());
  zip_source_close(out);
  zip_source_free(out);
  if (got != zip_int64_t(bytes.size()))
    Fail("SOG: reading the ZIP back failed");
  return bytes;
}

// --- meta.json ------------------------------------------------------------

const json& Member(const std::string& where, const json& object,
                   const char* key) {
  const auto it = object.find(key);
  if (it == object.end()) Fail(where + ": no '" + key + "'");
  return *it;
}

const json& ObjectMember(const std::string& where, const json& object,
                         const char* key) {
  const json& value = Member(where, object, key);
  if (!value.is_object()) Fail(where + ": '" + key + "' is not an object");
  return value;
}

std::vector<double> Numbers(const std::string& where, const json& object,
                            const char* key, size_t min_size, size_t max_size) {
  const json& value = Member(where, object, key);
  if (!value.is_array() || value.size() < min_size || value.size() > max_size) {
    Fail(where + ": '" + key + "' must be an array of " +
         std::to_string(min_size) +
         (max_size != min_size ? "-" + std::to_string(max_size) : "") +
         " numbers");
  }
  std::vector<double> numbers;
  for (const json& item : value) {
    if (!item.is_number() || !std::isfinite(item.get<double>())) {
      Fail(where + ": '" + key + "' holds a non-number or a non-finite value");
    }
    numbers.push_back(item.get<double>());
  }
  return numbers;
}

std::vector<std::string> FileNames(const std::string& where, const json& object,
                                   size_t count) {
  const json& value = Member(where, object, "files");
  if (!value.is_array() || value.size() < count) {
    Fail(where + ": 'files' must name " + std::to_string(count) + " file(s)");
  }
  std::vector<std::string> names;
  for (size_t i = 0; i < count; ++i) {
    if (!value[i].is_string()) Fail(where + ": 'files' holds a non-string");
    names.push_back(value[i].get<std::string>());
  }
  return names;
}

size_t Count(const std::string& where, const json& object, const char* key,
             size_t max) {
  const json& value = Member(where, object, key);
  if (!value.is_number_unsigned() || value.get<uint64_t>() > max) {
    Fail(where + ": '" + key + "' must be an integer in [0, " +
         std::to_string(max) + "]");
  }
  return size_t(value.get<uint64_t>());
}

// Loads a file the meta names: a ZIP member or a file beside meta.json.
using FileLoader = std::function<std::string(const std::string&)>;

class SogDecoder {
 public:
  SogDecoder(std::string name, const FileLoader& load)
      : name_(std::move(name)), load_(load) {}

  GaussianModel Decode(const std::string& meta_text, SogInfo* info) {
    const std::string where = name_ + ": meta.json";
    json meta;
    try {
      meta = json::parse(meta_text);
    } catch (const json::exception& e) {
      Fail(where + ": not JSON (" + Printable(e.what()) + ")");
    }
    if (!meta.is_object()) Fail(where + ": not a JSON object");
    if (!meta.contains("version")) {
      Fail(where +
           ": no 'version' (SOG version 1, PlayCanvas's first "
           "layout, is not read; convert it with splat-transform)");
    }
    if (!meta["version"].is_number_integer() || meta["version"] != 2) {
      Fail(where + ": version " +
           Printable(meta["version"].dump().substr(0, 40)) + ", expected 2");
    }
    count_ = Count(where, meta, "count", kMaxSogCount);
    if (info != nullptr && meta.contains("asset") &&
        meta["asset"].is_object() && meta["asset"].contains("generator") &&
        meta["asset"]["generator"].is_string()) {
      // Shown by ply_info: one printable line, however long the text.
      info->generator = Printable(
          meta["asset"]["generator"].get<std::string>().substr(0, 80));
    }
    int bands = 0;
    size_t palette = 0;
    if (meta.contains("shN")) {
      const json& sh = ObjectMember(where, meta, "shN");
      bands = int(Count(where + ".shN", sh, "bands", 3));
      palette = Count(where + ".shN", sh, "count", 65536);
      if (bands > 0 && palette == 0 && count_ > 0) {
        Fail(where + ".shN: 'count' is 0, the labels index nothing");
      }
    }
    GaussianModel model;
    model.sh_degree = bands;  // DecodeMeans sizes it once an image holds count
    DecodeMeans(where, ObjectMember(where, meta, "means"), &model);
    DecodeQuats(where, ObjectMember(where, meta, "quats"), &model);
    DecodeScales(where, ObjectMember(where, meta, "scales"), &model);
    DecodeSh0(where, ObjectMember(where, meta, "sh0"), &model);
    if (bands > 0) {
      DecodeShN(where, meta["shN"], bands, palette, &model);
    }
    if (info != nullptr) info->palette_size = bands > 0 ? palette : 0;
    return model;
  }

 private:
  Rgba Image(const std::string& file, size_t needed) const {
    return DecodeWebp(name_ + ": " + Printable(file), load_(file), needed);
  }

  void DecodeMeans(const std::string& where, const json& means,
                   GaussianModel* model) const {
    const std::string at = where + ".means";
    const std::vector<double> mins = Numbers(at, means, "mins", 3, 3);
    const std::vector<double> maxs = Numbers(at, means, "maxs", 3, 3);
    const std::vector<std::string> files = FileNames(at, means, 2);
    const Rgba low = Image(files[0], count_);
    const Rgba high = Image(files[1], count_);
    // Only now: a meta.json's count alone must not size the model (2^27
    // Gaussians of degree 3 are 31 GB); images of that many pixels bound it.
    model->Resize(count_);
    for (int axis = 0; axis < 3; ++axis) {
      // exp(88) is near float's largest: a range beyond would give Inf.
      if (std::abs(mins[axis]) > 88 || std::abs(maxs[axis]) > 88) {
        Fail(at + ": log-space range beyond +-88 (positions beyond float)");
      }
    }
    // As splat-transform reads it: a zero range spans 1.
    double range[3];
    for (int axis = 0; axis < 3; ++axis) {
      range[axis] = maxs[axis] != mins[axis] ? maxs[axis] - mins[axis] : 1.0;
    }
    for (size_t i = 0; i < count_; ++i) {
      for (int axis = 0; axis < 3; ++axis) {
        const int q = low.at(i)[axis] | (high.at(i)[axis] << 8);
        const double v =
            std::clamp(mins[axis] + range[axis] * (q / 65535.0), -88.0, 88.0);
        const double x = std::expm1(std::abs(v));
        model->means[3 * i + axis] = float(v < 0 ? -x : x);
      }
    }
  }

  void DecodeQuats(const std::string& where, const json& quats,
                   GaussianModel* model) const {
    const std::string file = FileNames(where + ".quats", quats, 1)[0];
    const Rgba image = Image(file, count_);
    static constexpr int kOthers[4][3] = {
        {1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    for (size_t i = 0; i < count_; ++i) {
      const uint8_t* p = image.at(i);
      if (p[3] < 252) {
        FailAt(name_ + ": " + Printable(file),
               "pixel " + std::to_string(i) + ": tag " + std::to_string(p[3]) +
                   ", expected 252-255");
      }
      const int largest = p[3] - 252;
      double q[4] = {0, 0, 0, 0};
      double sum = 0;
      for (int j = 0; j < 3; ++j) {
        q[kOthers[largest][j]] = (p[j] / 255.0 * 2 - 1) / std::sqrt(2.0);
        sum += q[kOthers[largest][j]] * q[kOthers[largest][j]];
      }
      q[largest] = std::sqrt(std::max(0.0, 1 - sum));
      for (int j = 0; j < 4; ++j) model->quats[4 * i + j] = float(q[j]);
    }
  }

  // Codebook of a property: up to 256 finite numbers (none for 0 Gaussians;
  // an index into a codebook too short is refused where it is used).
  std::vector<float> Codebook(const std::string& at, const json& object) const {
    const std::vector<double> values =
        Numbers(at, object, "codebook", 0, kCodebookSize);
    for (const double v : values) {
      // Finite in double but not in float (1e300) would become Inf.
      if (std::abs(v) > std::numeric_limits<float>::max()) {
        Fail(at + ": 'codebook' holds a value beyond float");
      }
    }
    return std::vector<float>(values.begin(), values.end());
  }

  float Lookup(const std::vector<float>& codebook, uint8_t index,
               const std::string& at, size_t i) const {
    if (index >= codebook.size()) {
      Fail(at + ": Gaussian " + std::to_string(i) + " indexes entry " +
           std::to_string(index) + " of a " + std::to_string(codebook.size()) +
           "-entry codebook");
    }
    return codebook[index];
  }

  // Three codebook indices a pixel (rgb) into `out` (N x 3); returns the
  // image, whose alpha sh0 uses.
  Rgba DecodeIndexed(const std::string& at, const json& object,
                     std::vector<float>* out) const {
    const std::vector<float> codebook = Codebook(at, object);
    Rgba image = Image(FileNames(at, object, 1)[0], count_);
    for (size_t i = 0; i < count_; ++i) {
      for (int j = 0; j < 3; ++j) {
        (*out)[3 * i + j] = Lookup(codebook, image.at(i)[j], at, i);
      }
    }
    return image;
  }

  void DecodeScales(const std::string& where, const json& scales,
                    GaussianModel* model) const {
    DecodeIndexed(where + ".scales", scales, &model->log_scales);
  }

  void DecodeSh0(const std::string& where, const json& sh0,
                 GaussianModel* model) const {
    const Rgba image = DecodeIndexed(where + ".sh0", sh0, &model->sh_dc);
    for (size_t i = 0; i < count_; ++i) {
      model->opacity_logits[i] = AlphaToOpacityLogit(image.at(i)[3] / 255.0);
    }
  }

  void DecodeShN(const std::string& where, const json& shn, int bands,
                 size_t palette, GaussianModel* model) const {
    const std::string at = where + ".shN";
    const std::vector<float> codebook = Codebook(at, shn);
    const std::vector<std::string> files = FileNames(at, shn, 2);
    const size_t coeffs = size_t(NumShCoeffs(bands) - 1);
    const size_t rows = (palette + kPaletteRow - 1) / kPaletteRow;
    const Rgba centroids = Image(files[0], rows * kPaletteRow * coeffs);
    if (size_t(centroids.width) != kPaletteRow * coeffs) {
      FailAt(name_ + ": " + Printable(files[0]),
             "width " + std::to_string(centroids.width) + ", expected " +
                 std::to_string(kPaletteRow * coeffs) + " for " +
                 std::to_string(bands) + " SH bands");
    }
    const Rgba labels = Image(files[1], count_);
    const size_t stride = size_t(model->sh_rest_stride());
    for (size_t i = 0; i < count_; ++i) {
      const size_t label = labels.at(i)[0] | (labels.at(i)[1] << 8);
      if (label >= palette) {
        FailAt(name_ + ": " + Printable(files[1]),
               "Gaussian " + std::to_string(i) + " has label " +
                   std::to_string(label) + " of a " + std::to_string(palette) +
                   "-entry palette");
      }
      const size_t first = (label / kPaletteRow) * size_t(centroids.width) +
                           (label % kPaletteRow) * coeffs;
      for (size_t j = 0; j < coeffs; ++j) {
        const uint8_t* p = centroids.at(first + j);
        for (int c = 0; c < 3; ++c) {
          model->sh_rest[i * stride + 3 * j + c] =
              Lookup(codebook, p[c], at, i);
        }
      }
    }
  }

  std::string name_;
  const FileLoader& load_;
  size_t count_ = 0;
};

// A file name a meta.json may use for a file beside it.
bool IsPlainFileName(const std::string& name) {
  return !name.empty() && name != "." && name != ".." &&
         name.find_first_of("/\\") == std::string::npos &&
         std::none_of(name.begin(), name.end(),
                      [](char c) { return uint8_t(c) < 0x20; });
}

}  // namespace

bool LooksLikeSogMeta(const uint8_t* data, size_t size) {
  size_t i = 0;
  while (i < size && std::isspace(data[i])) ++i;
  if (i == size || data[i] != '{') return false;
  const std::string head(reinterpret_cast<const char*>(data),
                         std::min(size, size_t(1) << 16));
  return head.find("\"means\"") != std::string::npos &&
         head.find("\"quats\"") != std::string::npos;
}

GaussianModel DecodeSogFiles(const std::string& name,
                             const std::string& meta_text,
                             const FileLoader& load, SogInfo* info) {
  return SogDecoder(name, load).Decode(meta_text, info);
}

GaussianModel DecodeSog(const std::string& name, const uint8_t* data,
                        size_t size, SogInfo* info) {
  const ZipArchive archive(name, data, size);
  const FileLoader load = [&archive](const std::string& file) {
    return archive.Read(file, kMaxMemberBytes);
  };
  if (info != nullptr) info->bundled = true;
  return DecodeSogFiles(name, archive.Read("meta.json", kMaxMetaBytes), load,
                        info);
}

GaussianModel ReadSogMeta(const std::string& meta_path, SogInfo* info) {
  const std::vector<uint8_t> meta = ReadFileBytes(meta_path);
  if (meta.size() > kMaxMetaBytes) FailAt(meta_path, "meta.json too large");
  const std::filesystem::path folder =
      std::filesystem::path(meta_path).parent_path();
  const FileLoader load = [&](const std::string& file) {
    if (!IsPlainFileName(file)) {
      FailAt(meta_path, "names '" + Printable(file) +
                            "': only files beside meta.json are read");
    }
    const std::vector<uint8_t> bytes = ReadFileBytes((folder / file).string());
    return std::string(bytes.begin(), bytes.end());
  };
  if (info != nullptr) info->bundled = false;
  return DecodeSogFiles(meta_path, std::string(meta.begin(), meta.end()), load,
                        info);
}

namespace {

// Images of one Gaussian a pixel, in the file's order.
struct SogLayout {
  size_t count = 0;
  int webp_method = 4;
  int width = 4;
  int height = 4;
  std::vector<uint8_t> NewImage() const {
    return std::vector<uint8_t>(4 * size_t(width) * size_t(height), 0);
  }
};

// splat-transform stores bytes through a Uint8Array: truncation, clamped.
uint8_t TruncatedByte(double value) {
  return uint8_t(std::clamp(value, 0.0, 255.0));
}

json EncodeMeans(const GaussianModel& model, const std::vector<uint32_t>& order,
                 const SogLayout& layout, std::string* low_webp,
                 std::string* high_webp) {
  // Clamped to the +-88 the reader accepts (float's largest is e^88.7).
  auto log_transform = [](double v) {
    return std::copysign(std::min(88.0, std::log1p(std::abs(v))), v);
  };
  double mins[3] = {0, 0, 0}, maxs[3] = {0, 0, 0};
  for (int axis = 0; axis < 3; ++axis) {
    mins[axis] = layout.count ? HUGE_VAL : 0;
    maxs[axis] = layout.count ? -HUGE_VAL : 0;
    for (size_t i = 0; i < layout.count; ++i) {
      const double v = log_transform(model.means[3 * i + axis]);
      mins[axis] = std::min(mins[axis], v);
      maxs[axis] = std::max(maxs[axis], v);
    }
  }
  std::vector<uint8_t> low = layout.NewImage(), high = layout.NewImage();
  for (size_t t = 0; t < layout.count; ++t) {
    for (int axis = 0; axis < 3; ++axis) {
      const double range = maxs[axis] - mins[axis];
      const double v = log_transform(model.means[3 * order[t] + axis]);
      const int q = range > 0 ? int(65535 * (v - mins[axis]) / range) : 0;
      low[4 * t + axis] = uint8_t(q & 0xff);
      high[4 * t + axis] = uint8_t((q >> 8) & 0xff);
    }
    low[4 * t + 3] = high[4 * t + 3] = 255;
  }
  *low_webp =
      EncodeWebpLossless(low, layout.width, layout.height, layout.webp_method);
  *high_webp =
      EncodeWebpLossless(high, layout.width, layout.height, layout.webp_method);
  return json{{"mins", {mins[0], mins[1], mins[2]}},
              {"maxs", {maxs[0], maxs[1], maxs[2]}},
              {"files", {"means_l.webp", "means_u.webp"}}};
}

std::string EncodeQuats(const GaussianModel& model,
                        const std::vector<uint32_t>& order,
                        const SogLayout& layout) {
  static constexpr int kOthers[4][3] = {
      {1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  std::vector<uint8_t> image = layout.NewImage();
  for (size_t t = 0; t < layout.count; ++t) {
    double q[4];
    double norm = 0;
    for (int j = 0; j < 4; ++j) {
      q[j] = model.quats[4 * order[t] + j];
      norm += q[j] * q[j];
    }
    norm = std::sqrt(norm);
    if (!(norm > 0)) {  // a zero quaternion renders as the identity
      q[0] = 1, q[1] = q[2] = q[3] = 0, norm = 1;
    }
    int largest = 0;
    for (int j = 1; j < 4; ++j) {
      if (std::abs(q[j]) > std::abs(q[largest])) largest = j;
    }
    const double sign = q[largest] < 0 ? -1 : 1;
    for (int j = 0; j < 3; ++j) {
      const double c = sign * q[kOthers[largest][j]] / norm * std::sqrt(2.0);
      image[4 * t + j] = TruncatedByte(255 * (c * 0.5 + 0.5));
    }
    image[4 * t + 3] = uint8_t(252 + largest);
  }
  return EncodeWebpLossless(image, layout.width, layout.height,
                            layout.webp_method);
}

// Three codebook indices (and optionally alpha) per Gaussian.
std::string EncodeIndexed(const std::vector<uint32_t>& labels,
                          const std::vector<uint32_t>& order,
                          const std::vector<uint8_t>* alpha,
                          const SogLayout& layout) {
  std::vector<uint8_t> image = layout.NewImage();
  for (size_t t = 0; t < layout.count; ++t) {
    for (int j = 0; j < 3; ++j) {
      image[4 * t + j] = uint8_t(labels[3 * order[t] + j]);
    }
    image[4 * t + 3] = alpha != nullptr ? (*alpha)[order[t]] : 255;
  }
  return EncodeWebpLossless(image, layout.width, layout.height,
                            layout.webp_method);
}

json EncodeShN(const GaussianModel& model, const std::vector<uint32_t>& order,
               const SogLayout& layout, const SogWriteOptions& options,
               std::string* centroids_webp, std::string* labels_webp) {
  const int coeffs = NumShCoeffs(model.sh_degree) - 1;
  const int dim = 3 * coeffs;
  size_t palette = 1;
  while (palette * 2 <= std::min<size_t>(layout.count, 65536)) palette *= 2;
  std::vector<float> centroids;
  std::vector<uint32_t> labels;
  // The palette is the slow part (33 s for 40k Gaussians on 2 cores): a
  // bar with an ETA where it takes more than a few seconds.
  std::unique_ptr<ProgressBar> bar;
  if (layout.count >= 16384) {
    bar = std::make_unique<ProgressBar>("sog palette",
                                        options.palette_iterations);
  }
  KMeans(model.sh_rest, dim, palette, options.palette_iterations, 0, &centroids,
         &labels, [&](int done) {
           if (bar) bar->Update(done, std::to_string(palette) + " entries");
         });
  if (bar) bar->Finish();
  std::vector<float> codebook;
  std::vector<uint32_t> value_labels;
  Quantize1d(centroids, kCodebookSize, &codebook, &value_labels);
  const size_t rows = (palette + kPaletteRow - 1) / kPaletteRow;
  const int width = int(kPaletteRow) * coeffs;
  std::vector<uint8_t> palette_image(4 * size_t(width) * rows, 0);
  for (size_t c = 0; c < palette; ++c) {
    for (int j = 0; j < coeffs; ++j) {
      uint8_t* p = &palette_image[4 * ((c / kPaletteRow) * width +
                                       (c % kPaletteRow) * coeffs + j)];
      for (int ch = 0; ch < 3; ++ch) {
        p[ch] = uint8_t(value_labels[c * dim + 3 * j + ch]);
      }
      p[3] = 255;
    }
  }
  std::vector<uint8_t> label_image = layout.NewImage();
  for (size_t t = 0; t < layout.count; ++t) {
    label_image[4 * t] = uint8_t(labels[order[t]] & 0xff);
    label_image[4 * t + 1] = uint8_t(labels[order[t]] >> 8);
    label_image[4 * t + 3] = 255;
  }
  *centroids_webp =
      EncodeWebpLossless(palette_image, width, int(rows), layout.webp_method);
  *labels_webp = EncodeWebpLossless(label_image, layout.width, layout.height,
                                    layout.webp_method);
  return json{{"count", palette},
              {"bands", model.sh_degree},
              {"codebook", codebook},
              {"files", {"shN_centroids.webp", "shN_labels.webp"}}};
}

}  // namespace

std::string EncodeSog(const GaussianModel& model,
                      const SogWriteOptions& options,
                      std::vector<uint32_t>* order_out) {
  if (model.CountNonFinite() > 0) Fail("SOG: the model holds NaN/Inf values");
  SogLayout layout;
  layout.count = model.size();
  layout.webp_method = options.webp_method;
  const double side = std::ceil(std::sqrt(double(layout.count)) / 4) * 4;
  layout.width = std::max(4, int(side));
  layout.height =
      std::max(4, int(std::ceil(double(layout.count) / layout.width / 4) * 4));
  const std::vector<uint32_t> order = MortonOrder(model);
  std::vector<std::pair<std::string, std::string>> files(5);
  json meta;
  meta["version"] = 2;
  meta["asset"] = {{"generator", "watergs"}};
  meta["count"] = layout.count;
  meta["means"] =
      EncodeMeans(model, order, layout, &files[0].second, &files[1].second);
  files[0].first = "means_l.webp";
  files[1].first = "means_u.webp";
  files[2] = {"quats.webp", EncodeQuats(model, order, layout)};
  meta["quats"] = {{"files", {"quats.webp"}}};
  std::vector<float> codebook;
  std::vector<uint32_t> labels;
  Quantize1d(model.log_scales, kCodebookSize, &codebook, &labels);
  files[3] = {"scales.webp", EncodeIndexed(labels, order, nullptr, layout)};
  meta["scales"] = {{"codebook", codebook}, {"files", {"scales.webp"}}};
  Quantize1d(model.sh_dc, kCodebookSize, &codebook, &labels);
  std::vector<uint8_t> alpha(layout.count);
  for (size_t i = 0; i < layout.count; ++i) {
    alpha[i] =
        TruncatedByte(OpacityLogitToAlpha(model.opacity_logits[i]) * 255);
  }
  files[4] = {"sh0.webp", EncodeIndexed(labels, order, &alpha, layout)};
  meta["sh0"] = {{"codebook", codebook}, {"files", {"sh0.webp"}}};
  if (model.sh_degree > 0 && layout.count > 0) {
    std::string centroids, label_image;
    meta["shN"] =
        EncodeShN(model, order, layout, options, &centroids, &label_image);
    files.emplace_back("shN_centroids.webp", std::move(centroids));
    files.emplace_back("shN_labels.webp", std::move(label_image));
  }
  files.insert(files.begin(), {"meta.json", meta.dump()});
  if (order_out != nullptr) *order_out = order;
  return ZipStore(files);
}

void WriteSog(const std::string& path, const GaussianModel& model,
              const SogWriteOptions& options) {
  const std::string bytes = EncodeSog(model, options);
  AtomicWriteFile(path, bytes);
}

}  // namespace watergs
