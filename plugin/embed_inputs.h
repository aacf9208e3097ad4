// What the embedding commands (`embed`, `concat_embed`) share: loading the
// raw model, the decoder, the message and the workspace's views in one order
// (so that both report a bad input the same way), the spread of check views,
// and the fidelity of a watermarked model against the raw one.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/rasterizer.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/message.h"

namespace watergs {

struct EmbedInputs {
  // The raw model and its file layout (to write the result the same way).
  PlyData ply;
  // The frozen decoder on the command's device.
  std::unique_ptr<BitDecoder> decoder;
  // The bits embedded: the owner's message, decoder->NumBits() long, XOR
  // the key's stream when a key is given (ApplyKey).
  Bits message;
  // The workspace (held by pointer: `views` refers to it) and its views.
  std::unique_ptr<Workspace> workspace;
  std::unique_ptr<WorkspaceViews> views;
  // Views to embed on (every view, or the training split with eval).
  std::vector<size_t> train_views;
};

// Reads the PLY, the decoder, the message (keyed by `key`, the resolved key,
// when not empty) and the workspace, in that order;
// throws Error naming the file at fault.
EmbedInputs LoadEmbedInputs(const std::string& input_path,
                            const std::string& decoder_path,
                            const std::string& message, const std::string& key,
                            const WorkspaceOptions& workspace, Device device,
                            bool eval);

// One line on stdout, "COMMAND: keyed message; key SHA-256 ..." (register
// it) or "COMMAND: unkeyed message: ..." (what its rate then holds for).
void PrintKeyNotice(const std::string& command, const std::string& key);

// `count` views spread evenly over `views`.
std::vector<size_t> SpreadViews(const std::vector<size_t>& views, int count);

struct Fidelity {
  // Mean over the views of the watermarked render's PSNR (dB) against the
  // ground truth and against the raw model's render, and of the raw render's
  // against the ground truth.
  double psnr_vs_truth = 0, psnr_vs_raw = 0, raw_psnr_vs_truth = 0;
};

// Whole-frame renders of `raw` and `marked` on `view_ids` of `views`.
Fidelity MeasureFidelity(Rasterizer& rasterizer, const GaussianModel& raw,
                         const GaussianModel& marked,
                         const TrainingViews& views,
                         const std::vector<size_t>& view_ids,
                         const std::array<float, 3>& background);

}  // namespace watergs
