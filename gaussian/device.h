// Where the compute runs: the CPU (always) or a CUDA GPU (when the build has
// the CUDA backend and a GPU is visible). Every command's `--device
// cpu|cuda|auto` goes through here, and so does the choice of rasterizer.
#pragma once

#include <iosfwd>
#include <memory>
#include <string>

#include "gaussian/rasterizer.h"

namespace watergs {

enum class Device { kCpu, kCuda };

// "cpu" or "cuda".
std::string DeviceName(Device device);

// Whether this build has the CUDA backend and a usable GPU is visible; when
// not, `why` (if not null) gets one line saying why ("built without CUDA",
// "no CUDA device visible: ...").
bool CudaAvailable(std::string* why = nullptr);

// "cpu", "cuda" or "auto" -> the device to use: auto picks CUDA when
// CudaAvailable(), else the CPU and says so, with why, on one stderr line
// once per process (a pipeline resolves the device of each stage). Throws
// Error for another word, and for "cuda" when CUDA is not available
// (saying why).
Device ResolveDevice(const std::string& text);
// The same with the note going to `note` unless *noted (then set): the
// process-wide one above is ResolveDevice(text, &std::cerr, &flag).
Device ResolveDevice(const std::string& text, std::ostream* note, bool* noted);

// The rasterizer for `device` (CPU: the OpenMP one; CUDA: cuda/).
std::unique_ptr<Rasterizer> MakeRasterizer(Device device);

}  // namespace watergs
