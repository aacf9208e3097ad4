// Device selection; the CUDA half lives in cuda/cuda_device.cc and is only
// compiled with the CUDA backend.
#include "gaussian/device.h"

#include <iostream>
#include <mutex>

#include "gaussian/util/error.h"

#ifdef WATERGS_WITH_CUDA
#include "gaussian/cuda/cuda_device.h"
#include "gaussian/cuda/cuda_rasterizer.h"
#endif

namespace watergs {

std::string DeviceName(Device device) {
  return device == Device::kCuda ? "cuda" : "cpu";
}

bool CudaAvailable(std::string* why) {
#ifdef WATERGS_WITH_CUDA
  return CudaDeviceVisible(why);
#else
  if (why) {
    *why =
        "this watergs was built without the CUDA backend (no nvcc at build "
        "time, or -DWATERGS_CUDA=OFF)";
  }
  return false;
#endif
}

Device ResolveDevice(const std::string& text, std::ostream* note, bool* noted) {
  if (text == "cpu") return Device::kCpu;
  if (text != "cuda" && text != "auto") {
    Fail("--device: expected cpu, cuda or auto, got '" + Printable(text) + "'");
  }
  std::string why;
  if (CudaAvailable(&why)) return Device::kCuda;
  if (text == "cuda") Fail("--device cuda: " + why);
  if (note && !*noted) {
    *note << "watergs: --device auto: running on the CPU (" << why << ")\n";
    *noted = true;
  }
  return Device::kCpu;
}

Device ResolveDevice(const std::string& text) {
  static std::mutex mutex;
  static bool noted = false;
  std::lock_guard<std::mutex> lock(mutex);
  return ResolveDevice(text, &std::cerr, &noted);
}

std::unique_ptr<Rasterizer> MakeRasterizer(Device device) {
  if (device == Device::kCpu) return MakeCpuRasterizer();
#ifdef WATERGS_WITH_CUDA
  return MakeCudaRasterizer();
#else
  Fail("--device cuda: built without the CUDA backend");
#endif
}

}  // namespace watergs
