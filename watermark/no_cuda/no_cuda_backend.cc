// watermark/backend.h in a build without the CUDA backend: decoders load and
// train on the CPU, and the embedding step runs on the host.
#include "gaussian/util/error.h"
#include "watermark/backend.h"

namespace watergs {

std::unique_ptr<BitDecoder> LoadGpuBitDecoder(const std::string& path, int,
                                              bool) {
  FailAt(path, "cannot load the decoder on the GPU: built without CUDA");
}

std::unique_ptr<BitDecoder> MakeGpuHiddenDecoder(HiddenModel&, bool) {
  Fail("decoder on the GPU: built without the CUDA backend");
}

std::unique_ptr<BitDecoder> MakeGpuFeatureDecoder(FeatureNet&, bool) {
  Fail("decoder on the GPU: built without the CUDA backend");
}

std::unique_ptr<DeviceDecoderTrainer> MakeGpuDecoderTrainer(HiddenModel&,
                                                            const NetworkAdam&,
                                                            bool) {
  Fail("train_decoder --device cuda: built without the CUDA backend");
}

DeviceEmbeddingStepFactory DeviceEmbeddingStepFor(Rasterizer&, BitDecoder&,
                                                  const EmbedOptions&, double,
                                                  const std::vector<float>&,
                                                  std::string*) {
  return nullptr;
}

}  // namespace watergs
