// Reading and writing COLMAP 3.8 sparse models (cameras, images, points3D) in
// both formats, byte-compatible with COLMAP: `.bin` (little-endian records)
// and `.txt` (the text `colmap model_converter --output_type TXT` writes).
// Readers validate everything and throw a one-line watergs::Error naming the
// file and the problem; no partial model is ever returned.
#pragma once

#include <string>

#include "plugin/reconstruction.h"

namespace watergs {

enum class ModelFormat { kBinary, kText };

// The folder holding the model files: `path` itself if it holds cameras.bin
// or cameras.txt, else <path>/sparse/0, else <path>/sparse. Throws Error
// naming `path` if none holds a model.
std::string FindModelPath(const std::string& path);

// Which format a model folder holds (binary wins if both are complete).
// Throws Error if neither the three .bin nor the three .txt files exist.
ModelFormat DetectModelFormat(const std::string& model_path);

// Reads a model from a workspace or model folder (FindModelPath) in whichever
// format is present. Every image in the files is registered, as in COLMAP.
Reconstruction ReadReconstruction(const std::string& path);

// Reads the three files of one format from a model folder.
Reconstruction ReadReconstructionBinary(const std::string& model_path);
Reconstruction ReadReconstructionText(const std::string& model_path);

// Writes cameras/images/points3D in `format` into `model_path` (created if
// missing) as a set (AtomicWriteFiles): on an error none of the three is
// replaced. Only registered images are written.
void WriteReconstruction(const Reconstruction& reconstruction,
                         const std::string& model_path, ModelFormat format);

// The exact contents COLMAP 3.8 writes for each file.
std::string CamerasText(const Reconstruction& reconstruction);
std::string ImagesText(const Reconstruction& reconstruction);
std::string Points3DText(const Reconstruction& reconstruction);
std::string CamerasBinary(const Reconstruction& reconstruction);
std::string ImagesBinary(const Reconstruction& reconstruction);
std::string Points3DBinary(const Reconstruction& reconstruction);

// "BIN" / "TXT" (case-insensitive) -> format; throws Error otherwise.
ModelFormat ParseModelFormat(const std::string& name);

}  // namespace watergs
