// Inputs and fidelity figures shared by the embedding commands.
#include "plugin/embed_inputs.h"

#include <algorithm>
#include <cstdio>

#include "gaussian/formats/model_io.h"
#include "gaussian/loss.h"
#include "watermark/message.h"

namespace watergs {

EmbedInputs LoadEmbedInputs(const std::string& input_path,
                            const std::string& decoder_path,
                            const std::string& message, const std::string& key,
                            const WorkspaceOptions& workspace, Device device,
                            bool eval) {
  EmbedInputs in;
  in.ply = ReadModelFile(input_path);
  in.decoder = LoadBitDecoder(decoder_path, device);
  in.message = ApplyKey(ParseMessage(message, in.decoder->NumBits()), key);
  in.workspace = std::make_unique<Workspace>(Workspace::Open(workspace));
  in.views = std::make_unique<WorkspaceViews>(*in.workspace);
  in.train_views = in.workspace->TrainViews(eval);
  return in;
}

void PrintKeyNotice(const std::string& command, const std::string& key) {
  if (!key.empty()) {
    std::printf(
        "%s: keyed message; key SHA-256 %s (register it now: a claim is "
        "evidence only if fixed before the suspect is read)\n",
        command.c_str(), KeyFingerprint(key).c_str());
  } else {
    std::printf(
        "%s: unkeyed message: its false-positive rate holds only for a claim "
        "fixed before the suspect is read, and text messages share bits "
        "(--key makes it exact: docs/verification.md)\n",
        command.c_str());
  }
}

std::vector<size_t> SpreadViews(const std::vector<size_t>& views, int count) {
  std::vector<size_t> out;
  const size_t n = std::min<size_t>(count, views.size());
  for (size_t k = 0; k < n; ++k) out.push_back(views[k * views.size() / n]);
  return out;
}

Fidelity MeasureFidelity(Rasterizer& rasterizer, const GaussianModel& raw,
                         const GaussianModel& marked,
                         const TrainingViews& views,
                         const std::vector<size_t>& view_ids,
                         const std::array<float, 3>& background) {
  Fidelity f;
  if (view_ids.empty()) return f;
  ImageRGB raw_image, marked_image;
  RenderOptions options;
  options.background = background;
  for (size_t v : view_ids) {
    rasterizer.Forward(raw, views.Camera(v), options, &raw_image, nullptr);
    rasterizer.Forward(marked, views.Camera(v), options, &marked_image,
                       nullptr);
    for (float& x : raw_image.data) x = std::clamp(x, 0.f, 1.f);
    f.psnr_vs_raw += Psnr(marked_image, raw_image) / view_ids.size();
    f.psnr_vs_truth += Psnr(marked_image, *views.Image(v)) / view_ids.size();
    f.raw_psnr_vs_truth += Psnr(raw_image, *views.Image(v)) / view_ids.size();
  }
  return f;
}

}  // namespace watergs
