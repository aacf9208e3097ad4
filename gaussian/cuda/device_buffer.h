// An owning, typed device allocation (cudaMalloc/cudaFree) with host copies.
// Move-only; sizes are element counts. Used by every CUDA module so that no
// raw cudaMalloc leaks on an exception.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <utility>
#include <vector>

#include "gaussian/cuda/cuda_check.h"

namespace watergs {

template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(size_t count) { Resize(count); }
  ~DeviceBuffer() { Free(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& other) noexcept { *this = std::move(other); }
  DeviceBuffer& operator=(DeviceBuffer&& other) noexcept {
    if (this != &other) {
      Free();
      data_ = std::exchange(other.data_, nullptr);
      size_ = std::exchange(other.size_, 0);
      capacity_ = std::exchange(other.capacity_, 0);
    }
    return *this;
  }

  // Sets the size to `count`; reallocates (contents lost) only when it grows
  // past the capacity, so per-iteration buffers are allocated once.
  void Resize(size_t count) {
    if (count > capacity_) {
      Free();
      if (count > 0) {
        WATERGS_CUDA_CHECK(cudaMalloc(&data_, count * sizeof(T)));
      }
      capacity_ = count;
    }
    size_ = count;
  }
  // Copies `host` to the device (resizing to its size).
  void Upload(const std::vector<T>& host) { Upload(host.data(), host.size()); }
  void Upload(const T* host, size_t count) {
    Resize(count);
    if (count > 0) {
      WATERGS_CUDA_CHECK(
          cudaMemcpy(data_, host, count * sizeof(T), cudaMemcpyHostToDevice));
    }
  }
  // Copies the device contents to `host` (resized).
  void Download(std::vector<T>* host) const {
    host->resize(size_);
    if (size_ > 0) {
      WATERGS_CUDA_CHECK(cudaMemcpy(host->data(), data_, size_ * sizeof(T),
                                    cudaMemcpyDeviceToHost));
    }
  }
  // Sets every byte to zero.
  void Zero() {
    if (size_ > 0) WATERGS_CUDA_CHECK(cudaMemset(data_, 0, size_ * sizeof(T)));
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  size_t size() const { return size_; }
  size_t bytes() const { return size_ * sizeof(T); }

 private:
  void Free() {
    if (data_) cudaFree(data_);
    data_ = nullptr;
    size_ = capacity_ = 0;
  }

  // Device pointer (null when empty).
  T* data_ = nullptr;
  // Elements in use and allocated.
  size_t size_ = 0, capacity_ = 0;
};

}  // namespace watergs
