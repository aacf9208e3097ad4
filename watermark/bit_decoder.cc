// LoadBitDecoder: the CPU Decoder, or with the CUDA backend the CudaDecoder
// read from the same weights file.
#include "watermark/bit_decoder.h"

#include "gaussian/error.h"
#include "watermark/decoder.h"

#ifdef WATERGS_WITH_CUDA
#include "watermark/cuda/cuda_hidden.h"
#endif

namespace watergs {

std::unique_ptr<BitDecoder> LoadBitDecoder(const std::string& path,
                                           Device device, int expected_bits) {
  if (device == Device::kCpu) {
    return std::make_unique<Decoder>(Decoder::Load(path, expected_bits));
  }
  std::string why;
  if (!CudaAvailable(&why)) {
    FailAt(path, "cannot load the decoder on the GPU: " + why);
  }
#ifdef WATERGS_WITH_CUDA
  // No TF32: the GPU decoder then reads what the CPU one does (parity tests).
  return std::make_unique<CudaDecoder>(
      CudaDecoder::Load(path, expected_bits, false));
#else
  FailAt(path, "cannot load the decoder on the GPU: built without CUDA");
#endif
}

}  // namespace watergs
