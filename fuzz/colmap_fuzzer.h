// One COLMAP model file fuzzed at a time (cameras, images or points3D, .bin
// or .txt): the fuzzed bytes become that file of a model folder whose other
// two files are fixed and valid (the demo subset's files that the fuzzed one
// may refer to, empty ones otherwise), and the folder is read with the public
// reader. A model that reads must also survive being written in the same
// format and read again with the same counts.
#pragma once

#include <string>

#include "fuzz/fuzz_support.h"
#include "plugin/reconstruction_io.h"

namespace watergs::fuzz {

enum class ColmapFile { kCameras, kImages, kPoints3D };

// The demo subset cut down to what `file` may refer to: cameras for the
// images file, cameras and images for points3D, nothing for cameras.
inline Reconstruction CompanionModel(ColmapFile file) {
  const Reconstruction subset = DemoSubset();
  Reconstruction companion;
  if (file == ColmapFile::kCameras) return companion;
  for (const auto& [id, camera] : subset.Cameras()) {
    companion.AddCamera(camera);
  }
  if (file == ColmapFile::kImages) return companion;
  for (const image_t id : subset.RegImageIds()) {
    companion.AddImage(subset.GetImage(id));
    companion.RegisterImage(id);
  }
  return companion;
}

inline std::string ColmapFileName(ColmapFile file, ModelFormat format) {
  static const char* kNames[] = {"cameras", "images", "points3D"};
  return std::string(kNames[static_cast<int>(file)]) +
         (format == ModelFormat::kBinary ? ".bin" : ".txt");
}

// The model folder with the companion files, written once per process.
inline const std::string& CompanionFolder(ColmapFile file, ModelFormat format) {
  static const std::string folder = [&] {
    const std::string dir = ScratchDir() + "/model";
    WriteReconstruction(CompanionModel(file), dir, format);
    return dir;
  }();
  return folder;
}

inline int FuzzColmapFile(ColmapFile file, ModelFormat format,
                          const uint8_t* data, size_t size) {
  const std::string& dir = CompanionFolder(file, format);
  WriteBytes(dir + "/" + ColmapFileName(file, format), data, size);
  Reconstruction model;
  try {
    model = format == ModelFormat::kBinary ? ReadReconstructionBinary(dir)
                                           : ReadReconstructionText(dir);
  } catch (const Error& e) {
    ExpectOneLineError(e, dir);
    return 0;
  }
  const std::string again = ScratchDir() + "/again";
  try {
    WriteReconstruction(model, again, format);
    const Reconstruction reread = format == ModelFormat::kBinary
                                      ? ReadReconstructionBinary(again)
                                      : ReadReconstructionText(again);
    if (reread.NumCameras() != model.NumCameras() ||
        reread.NumRegImages() != model.NumRegImages() ||
        reread.NumPoints3D() != model.NumPoints3D()) {
      Finding("model read back with other counts");
    }
  } catch (const Error& e) {
    Finding(std::string("a model that was read cannot be written and read "
                        "back: ") +
            e.what());
  }
  return 0;
}

}  // namespace watergs::fuzz
