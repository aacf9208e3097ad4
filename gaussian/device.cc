// Device selection; what the backend offers comes through gaussian/backend.h.
#include "gaussian/device.h"

#include <iostream>
#include <mutex>

#include "gaussian/backend.h"
#include "gaussian/util/error.h"

namespace watergs {

std::string DeviceName(Device device) {
  return device == Device::kCuda ? "cuda" : "cpu";
}

bool CudaAvailable(std::string* why) { return GpuBackendAvailable(why); }

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
  return MakeGpuRasterizer();
}

}  // namespace watergs
