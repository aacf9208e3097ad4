// LoadBitDecoder: by the weights file's kind, the random-feature decoder
// (CPU; it costs a few hundred multiply-adds a pixel, so a GPU run keeps it
// on the host), or the HiDDeN decoder: the CPU Decoder, or with the CUDA
// backend the CudaDecoder read from the same file.
#include "watermark/bit_decoder.h"

#include "gaussian/error.h"
#include "watermark/decoder.h"
#include "watermark/feature_decoder.h"
#include "watermark/network_file.h"

#ifdef WATERGS_WITH_CUDA
#include "watermark/cuda/cuda_hidden.h"
#endif

namespace watergs {

std::unique_ptr<BitDecoder> LoadBitDecoder(const std::string& path,
                                           Device device, int expected_bits) {
  const NetworkFile file = ReadNetworkFile(path);
  if (file.kind == kFeatureDecoderKind)
    return std::make_unique<FeatureDecoder>(
        FeatureNetFromFile(path, file, expected_bits));
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
