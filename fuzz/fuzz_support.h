// Shared pieces of the libFuzzer targets and the seed generator: a scratch
// folder for readers that take a path, the checksum fix-up that lets the
// fuzzer reach the parsers behind a checksum, the small valid inputs the
// seeds are made from, and the rule of every target: watergs::Error is the
// expected refusal, anything else (crash, other exception, sanitizer report,
// broken invariant) is a finding.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/util/error.h"
#include "plugin/reconstruction.h"
#include "plugin/reconstruction_io.h"

namespace watergs::fuzz {

// Splits the files of an unbundled SOG in sog_fuzzer's inputs.
inline constexpr char kSogFuzzSeparator[] = "\n--sog-file--\n";

// Per-process scratch folder (tmpfs when there is one), removed at exit. The
// name is never destroyed, so the exit handler can still use it.
inline const std::string& ScratchDir() {
  static const std::string* const dir = [] {
    const char* root =
        std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
    auto* path = new std::string(std::string(root) + "/watergs_fuzz_XXXXXX");
    if (mkdtemp(path->data()) == nullptr) {
      std::perror("mkdtemp");
      std::abort();
    }
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(ScratchDir(), ec);
    });
    return path;
  }();
  return *dir;
}

// Writes `size` bytes to `path` (plain write: the reader under test, not the
// writer, is what is fuzzed).
inline void WriteBytes(const std::string& path, const uint8_t* data,
                       size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data),
            static_cast<std::streamsize>(size));
  if (!out) {
    std::perror(path.c_str());
    std::abort();
  }
}

// ScratchDir()/name holding the bytes; returns its path.
inline std::string WriteScratchFile(const std::string& name,
                                    const uint8_t* data, size_t size) {
  const std::string path = ScratchDir() + "/" + name;
  WriteBytes(path, data, size);
  return path;
}

// Reports a broken invariant: libFuzzer keeps the input as a crash.
[[noreturn]] inline void Finding(const std::string& what) {
  std::fprintf(stderr, "FUZZ FINDING: %s\n", what.c_str());
  std::abort();
}

// Checks a refusal the way the CLI prints it: one line (no newline copied
// from the input) that starts with the offending file's path, when given.
inline void ExpectOneLineError(const Error& error,
                               const std::string& path = "") {
  const std::string message = error.what();
  if (message.empty() || message.find('\n') != std::string::npos) {
    Finding("error message is not one line: " + message);
  }
  if (!path.empty() && message.rfind(path, 0) != 0) {
    Finding("error message does not start with " + path + ": " + message);
  }
}

// Overwrites the trailing u64 of `bytes` with `hash(everything before it)`,
// so that mutated files pass the checksum and reach the parser behind it.
template <typename Hash>
std::vector<uint8_t> WithValidChecksum(const uint8_t* data, size_t size,
                                       Hash hash) {
  std::vector<uint8_t> bytes(data, data + size);
  if (bytes.size() >= sizeof(uint64_t)) {
    const size_t body = bytes.size() - sizeof(uint64_t);
    const uint64_t sum = hash(bytes.data(), body);
    std::memcpy(bytes.data() + body, &sum, sizeof(sum));
  }
  return bytes;
}

// A small valid model: n Gaussians of `sh_degree` with varied finite values.
inline GaussianModel SmallModel(size_t n, int sh_degree, uint32_t seed) {
  GaussianModel model;
  model.sh_degree = sh_degree;
  model.Resize(n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  for (auto* array : {&model.means, &model.log_scales, &model.quats,
                      &model.opacity_logits, &model.sh_dc, &model.sh_rest}) {
    for (float& v : *array) v = u(rng);
  }
  return model;
}

// The committed demo scene's sparse model cut to a few images and points
// (every reference kept valid), so that seeds stay a few KB.
inline Reconstruction DemoSubset() {
  const Reconstruction full = ReadReconstruction(
      std::string(WATERGS_SOURCE_DIR) + "/datasets_scripts/demo_scene");
  constexpr size_t kImages = 3, kPoints2D = 24, kPoints3D = 16;
  std::vector<image_t> image_ids = full.RegImageIds();
  std::sort(image_ids.begin(), image_ids.end());
  image_ids.resize(std::min(image_ids.size(), kImages));
  Reconstruction subset;
  for (const image_t id : image_ids) {
    Image image = full.GetImage(id);
    image.points2D.resize(std::min(image.points2D.size(), kPoints2D));
    if (!subset.ExistsCamera(image.camera_id)) {
      subset.AddCamera(full.GetCamera(image.camera_id));
    }
    subset.AddImage(std::move(image));
    subset.RegisterImage(id);
  }
  for (const auto& [id, point3D] : full.Points3D()) {
    if (subset.NumPoints3D() == kPoints3D) break;
    Point3D kept = point3D;
    kept.track.clear();
    for (const TrackElement& element : point3D.track) {
      if (subset.ExistsImage(element.image_id) &&
          element.point2D_idx < kPoints2D) {
        kept.track.push_back(element);
      }
    }
    if (!kept.track.empty()) subset.AddPoint3D(id, std::move(kept));
  }
  return subset;
}

}  // namespace watergs::fuzz
