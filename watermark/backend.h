// The boundary between the watermark layer and its compute backends (as
// gaussian/backend.h is the engine's): loading a decoder on the GPU, decoder
// training steps there, and the device-resident embedding step. Defined by
// watermark/cuda/cuda_backend.cc when the build has CUDA and by
// watermark/no_cuda/no_cuda_backend.cc otherwise; the embedder, the decoder
// loader and decoder training name no backend type.
#pragma once

#include <memory>
#include <random>
#include <string>
#include <vector>

#include "gaussian/rasterizer.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/device_embedding_step.h"
#include "watermark/embedder.h"
#include "watermark/feature_decoder.h"

namespace watergs {

// Decoder training steps whose model and Adam state live on a device.
class DeviceDecoderTrainer {
 public:
  virtual ~DeviceDecoderTrainer() = default;
  // One step on a host batch: cover [N,3,H,W] in [-1,1], N*L target bits.
  virtual StepResult Step(ImageNoise& noise, NoiseKind kind,
                          const Tensor& cover,
                          const std::vector<float>& targets, float image_weight,
                          std::mt19937* rng) = 0;
  // The device's weights, statistics and Adam state into the host copies.
  virtual void CopyToHost(HiddenModel* model, NetworkAdam* adam) = 0;
};

// The decoder in `path` on the GPU (`feature`: the random-feature kind, else
// HiDDeN), reading what the CPU one reads (no TF32). Error naming `path`
// without a GPU backend.
std::unique_ptr<BitDecoder> LoadGpuBitDecoder(const std::string& path,
                                              int expected_bits, bool feature);

// The GPU twins of a HiDDeN decoder and of a random-feature decoder built
// from host weights (which must outlive them); allow_tf32 trades the CPU's
// exact reading for speed. Error without a GPU backend.
std::unique_ptr<BitDecoder> MakeGpuHiddenDecoder(HiddenModel& model,
                                                 bool allow_tf32);
std::unique_ptr<BitDecoder> MakeGpuFeatureDecoder(FeatureNet& net,
                                                  bool allow_tf32);

// Decoder training steps on the GPU, starting from `model` and `adam`.
// Error without a GPU backend.
std::unique_ptr<DeviceDecoderTrainer> MakeGpuDecoderTrainer(
    HiddenModel& model, const NetworkAdam& adam, bool allow_tf32);

// The device-resident embedding step for this rasterizer and decoder, or an
// empty factory: then *host_step_reason names the option that keeps the
// step on the host when the backend could otherwise have run it (left empty
// when it cannot: a CPU rasterizer or decoder). `targets` are the message's
// bits as floats.
DeviceEmbeddingStepFactory DeviceEmbeddingStepFor(
    Rasterizer& rasterizer, BitDecoder& decoder, const EmbedOptions& options,
    double scene_extent, const std::vector<float>& targets,
    std::string* host_step_reason);

}  // namespace watergs
