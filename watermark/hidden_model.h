// A HiDDeN encoder/decoder pair and its weights file ("hidden-model" kind of
// the network container, see network_file.h). The file's meta fields record
// the architecture: num_bits, channels, encoder_blocks, decoder_blocks,
// has_encoder, input_range (1: images in [-1,1]), message_input (1: +-1),
// size_independent (1: any H x W). Every tensor the architecture implies must
// be present with its exact shape, and no other.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "watermark/hidden_net.h"
#include "watermark/network_file.h"

namespace watergs {

struct HiddenModel {
  // Architecture of both networks.
  HiddenConfig config;
  // Null in a decoder-only file.
  std::unique_ptr<HiddenEncoder> encoder;
  // Always present.
  std::unique_ptr<HiddenDecoder> decoder;

  // Randomly initialised networks (PyTorch's default initialisation).
  HiddenModel(const HiddenConfig& config, bool with_encoder, uint32_t seed);
  std::vector<Parameter*> EncoderParameters();
  std::vector<Parameter*> DecoderParameters();
  // Encoder then decoder parameters.
  std::vector<Parameter*> AllParameters();
};

// The model as a network file (architecture meta + every tensor).
NetworkFile HiddenModelToFile(HiddenModel& model, bool include_encoder);
// Builds the model a file describes; `path` names it in errors. Refuses
// unknown kinds, missing/extra/misshapen tensors, non-finite weights, a
// missing encoder when need_encoder, and num_bits != expected_bits when
// expected_bits > 0.
std::unique_ptr<HiddenModel> HiddenModelFromFile(const std::string& path,
                                                 const NetworkFile& file,
                                                 bool need_encoder,
                                                 int expected_bits = 0);

// Atomic save / checked load of a weights file.
void SaveHiddenModel(const std::string& path, HiddenModel& model,
                     bool include_encoder);
std::unique_ptr<HiddenModel> LoadHiddenModel(const std::string& path,
                                             bool need_encoder,
                                             int expected_bits = 0);

}  // namespace watergs
