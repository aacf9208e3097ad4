// HiDDeN model construction and its weights file (see hidden_model.h).
#include "watermark/hidden_model.h"

#include <cmath>
#include <sstream>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

constexpr char kModelKind[] = "hidden-model";

std::string ShapeText(const std::vector<int>& shape) {
  std::ostringstream s;
  s << "[";
  for (size_t i = 0; i < shape.size(); ++i) s << (i ? "x" : "") << shape[i];
  s << "]";
  return s.str();
}

}  // namespace

HiddenModel::HiddenModel(const HiddenConfig& config_, bool with_encoder,
                         uint32_t seed)
    : config(config_) {
  std::mt19937 rng(seed);
  if (with_encoder) encoder = std::make_unique<HiddenEncoder>(config, &rng);
  decoder = std::make_unique<HiddenDecoder>(config, &rng);
}

std::vector<Parameter*> HiddenModel::EncoderParameters() {
  std::vector<Parameter*> params;
  if (encoder) encoder->CollectParameters(&params);
  return params;
}

std::vector<Parameter*> HiddenModel::DecoderParameters() {
  std::vector<Parameter*> params;
  decoder->CollectParameters(&params);
  return params;
}

std::vector<Parameter*> HiddenModel::AllParameters() {
  std::vector<Parameter*> params = EncoderParameters();
  for (Parameter* p : DecoderParameters()) params.push_back(p);
  return params;
}

NetworkFile HiddenModelToFile(HiddenModel& model, bool include_encoder) {
  NetworkFile file;
  file.kind = kModelKind;
  const bool has_encoder = include_encoder && model.encoder;
  file.meta = {{"num_bits", model.config.num_bits},
               {"channels", model.config.channels},
               {"encoder_blocks", model.config.encoder_blocks},
               {"decoder_blocks", model.config.decoder_blocks},
               {"has_encoder", has_encoder ? 1 : 0},
               {"input_range", 1},
               {"message_input", 1},
               {"size_independent", 1}};
  std::vector<Parameter*> params =
      has_encoder ? model.AllParameters() : model.DecoderParameters();
  for (const Parameter* p : params)
    file.tensors.push_back(TensorRecord{p->name, p->shape, p->value});
  return file;
}

std::unique_ptr<HiddenModel> HiddenModelFromFile(const std::string& path,
                                                 const NetworkFile& file,
                                                 bool need_encoder,
                                                 int expected_bits) {
  if (file.kind != kModelKind && file.kind != "hidden-checkpoint")
    FailAt(path, "holds a '" + file.kind + "', not a HiDDeN model");
  HiddenConfig config;
  config.num_bits = int(file.Meta("num_bits", path));
  config.channels = int(file.Meta("channels", path));
  config.encoder_blocks = int(file.Meta("encoder_blocks", path));
  config.decoder_blocks = int(file.Meta("decoder_blocks", path));
  const bool has_encoder = file.Meta("has_encoder", path) != 0;
  if (file.Meta("input_range", path) != 1 ||
      file.Meta("message_input", path) != 1)
    FailAt(path, "wrong architecture: unknown input or message convention");
  if (config.num_bits < 1 || config.num_bits > 1024 || config.channels < 1 ||
      config.channels > 1024 || config.encoder_blocks < 1 ||
      config.encoder_blocks > 64 || config.decoder_blocks < 1 ||
      config.decoder_blocks > 64)
    FailAt(path, "wrong architecture: implausible layer sizes");
  if (expected_bits > 0 && config.num_bits != expected_bits)
    FailAt(path, "wrong architecture: decoder reads " +
                     std::to_string(config.num_bits) + " bits, " +
                     std::to_string(expected_bits) + " expected");
  if (need_encoder && !has_encoder)
    FailAt(path, "holds no encoder (decoder-only file)");
  // The networks are allocated before their tensors are matched, and a few
  // bytes of meta must not ask for gigabytes: the file must hold at least the
  // convolution weights the architecture implies.
  const int64_t c = config.channels, bits = config.num_bits;
  int64_t needed = 9 * c * (3 + (config.decoder_blocks - 1) * c + bits);
  if (has_encoder)
    needed += 9 * c * (3 + (config.encoder_blocks - 1) * c + bits + c + 3);
  int64_t stored_values = 0;
  for (const TensorRecord& t : file.tensors)
    stored_values += int64_t(t.values.size());
  if (stored_values < needed)
    FailAt(path, "wrong architecture: the file holds " +
                     std::to_string(stored_values) +
                     " weights, the architecture needs at least " +
                     std::to_string(needed));
  auto model = std::make_unique<HiddenModel>(config, has_encoder, 0);
  std::vector<Parameter*> params = model->AllParameters();
  size_t stored = 0;
  for (Parameter* p : params) {
    const TensorRecord* t = file.Find(p->name);
    if (!t) FailAt(path, "wrong architecture: missing tensor " + p->name);
    if (t->shape != p->shape)
      FailAt(path, "wrong architecture: tensor " + p->name + " is " +
                       ShapeText(t->shape) + ", expected " +
                       ShapeText(p->shape));
    for (float v : t->values)
      if (!std::isfinite(v))
        FailAt(path, "corrupted: non-finite value in tensor " + p->name);
    p->value = t->values;
    ++stored;
  }
  const bool checkpoint = file.kind != kModelKind;
  if (!checkpoint && stored != file.tensors.size())
    FailAt(path, "wrong architecture: " +
                     std::to_string(file.tensors.size() - stored) +
                     " tensors the architecture does not have");
  return model;
}

void SaveHiddenModel(const std::string& path, HiddenModel& model,
                     bool include_encoder) {
  WriteNetworkFile(path, HiddenModelToFile(model, include_encoder));
}

std::unique_ptr<HiddenModel> LoadHiddenModel(const std::string& path,
                                             bool need_encoder,
                                             int expected_bits) {
  return HiddenModelFromFile(path, ReadNetworkFile(path), need_encoder,
                             expected_bits);
}

}  // namespace watergs
