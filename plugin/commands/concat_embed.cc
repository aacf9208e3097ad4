// `watergs concat_embed`: the paper's "CONCAT + 3DGS" baseline. Trains an
// explicit encoder that writes a message into the SH coefficients of a
// trained 3DGS model (watermark/concat_encoder.h), applies it once with the
// owner's message, and writes the PLY in the input's layout (every attribute
// other than the chosen SH groups bit-identical to the input).
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "plugin/command.h"
#include "plugin/embed_inputs.h"
#include "plugin/option_parser.h"
#include "watermark/bit_decoder.h"
#include "watermark/concat_encoder.h"
#include "watermark/extractor.h"
#include "watermark/message.h"

namespace watergs {
namespace {

struct ConcatArgs {
  std::string input_path, output_path, decoder_path, message, key_option;
  WorkspaceOptions workspace;
  int64_t iterations = 2000;
  double gamma = 0.3, beta = 0.2, learning_rate = 1e-3;
  std::string attributes = "sh";
  int hidden = 64;
  int crop_size = 128;
  int check_views = 4;
  std::string background = "0,0,0";
  int64_t seed = 0;
  int num_threads = 0;
  // --split: all, or train (every 8th view held out, so that eval scores
  // unseen views); eval: split == "train".
  std::string split = "all";
  bool eval = false;
};

void Validate(const ConcatArgs& a) {
  if (SamePath(a.input_path, a.output_path)) {
    Fail("concat_embed: --output_path must differ from --input_path");
  }
  if (a.iterations < 0) Fail("--iterations must be >= 0");
  if (!(a.gamma >= 0)) Fail("--gamma must be >= 0");
  if (!(a.beta >= 0 && a.beta <= 1)) Fail("--beta must be in [0, 1]");
  if (!(a.learning_rate > 0)) Fail("--learning_rate must be > 0");
  if (a.hidden < 1) Fail("--hidden must be at least 1");
  if (a.crop_size < 0) Fail("--crop_size must be >= 0 (0 = whole frames)");
  if (a.check_views < 1) Fail("--check_views must be at least 1");
  CheckOutputFile(a.output_path);  // before the training, not after
}

// The message read from whole-frame renders of `model` on `views`.
ExtractionResult Decode(Rasterizer& rasterizer, const GaussianModel& model,
                        const TrainingViews& views,
                        const std::vector<size_t>& view_ids,
                        BitDecoder& decoder, const Bits& message,
                        const std::array<float, 3>& background) {
  std::vector<RenderCamera> cameras;
  std::vector<std::string> names;
  for (size_t v : view_ids) {
    cameras.push_back(views.Camera(v));
    names.push_back(views.Name(v));
  }
  return ExtractWatermark(rasterizer, model, cameras, names, decoder, &message,
                          background, VerificationThresholds{});
}

void AddOptions(OptionParser* parser, ConcatArgs* a) {
  parser->AddRequired(
      "input_path", &a->input_path,
      "Trained 3DGS model (PLY, compressed PLY, .spz, .splat or SOG)");
  parser->AddRequired("workspace_path", &a->workspace.workspace_path,
                      "COLMAP workspace the model was trained on");
  parser->Add("sparse_path", &a->workspace.input_path,
              "Sparse model folder (default <workspace>/sparse/0)");
  parser->Add("image_path", &a->workspace.image_path,
              "Image folder (default <workspace>/images)");
  parser->Add("downscale", &a->workspace.downscale, "Image downscale: 1,2,4,8");
  a->decoder_path = ShippedDecoderPath();
  parser->Add("decoder", &a->decoder_path, kDecoderHelp);
  parser->AddRequired("message", &a->message,
                      std::string("Message: ") + kMessageFormats);
  parser->Add("key", &a->key_option, kKeyHelp);
  parser->AddRequired("output_path", &a->output_path, "Watermarked PLY");
  parser->Add("iterations", &a->iterations, "Encoder training iterations");
  parser->Add("gamma", &a->gamma, "Weight of the message loss");
  parser->Add("beta", &a->beta, "Weight of D-SSIM in the image loss");
  parser->Add("attributes", &a->attributes,
              "SH groups the encoder writes: f_dc, f_rest or sh (both)");
  parser->Add("hidden", &a->hidden, "Width of the encoder's hidden layer");
  parser->Add("learning_rate", &a->learning_rate, "Adam step size");
  parser->Add("crop_size", &a->crop_size,
              "Side of the random crop rendered per iteration (0 = frames)");
  parser->Add("check_views", &a->check_views,
              "Views decoded before and after (BER, PSNR)");
  parser->Add("background", &a->background, "r,g,b, black or white");
  parser->Add("seed", &a->seed, "Random seed");
  parser->Add("num_threads", &a->num_threads, "Threads (0 = all cores)");
  parser->Add("split", &a->split,
              "Views to train on: all, or train (all but every 8th view, as "
              "train --split train holds out, so that eval scores unseen "
              "views)");
  parser->AddAlias("eval", "split", "train");
}

int RunConcatEmbed(int argc, char** argv) {
  ConcatArgs a;
  OptionParser parser("concat_embed",
                      "CONCAT + 3DGS baseline: trains an explicit encoder "
                      "that offsets the SH coefficients by E(h, m), then "
                      "writes the model encoded with the message.");
  AddOptions(&parser, &a);
  if (!parser.Parse(argc, argv)) return 0;
  if (a.split != "all" && a.split != "train") {
    Fail("concat_embed: --split all or train, not '" + a.split + "'");
  }
  a.eval = a.split == "train";
  Validate(a);
  if (a.num_threads > 0) omp_set_num_threads(a.num_threads);
  ConcatTrainOptions options;
  options.iterations = a.iterations;
  options.gamma = a.gamma;
  options.beta = a.beta;
  options.learning_rate = a.learning_rate;
  options.crop_size = a.crop_size;
  options.seed = static_cast<uint64_t>(a.seed);
  options.background = ParseBackground(a.background);
  options.show_progress = true;
  const ShTarget target = ParseShTarget(a.attributes);

  const std::string key = ResolveKey(a.key_option);
  EmbedInputs in = LoadEmbedInputs(a.input_path, a.decoder_path, a.message, key,
                                   a.workspace, parser.device(), a.eval);
  PrintKeyNotice("concat_embed", key);
  const GaussianModel& raw = in.ply.model;
  ConcatEncoder encoder(target, raw.sh_degree, in.decoder->NumBits(), a.hidden,
                        static_cast<uint32_t>(a.seed));
  const std::vector<size_t> check_views =
      SpreadViews(in.train_views, a.check_views);
  std::printf(
      "concat_embed: %zu Gaussians, %zu views, %d-bit message %s, encoder on "
      "%s (%d coefficients, hidden %d), crop %d, %d threads\n",
      raw.size(), in.train_views.size(), in.decoder->NumBits(),
      BitsToHex(in.message).c_str(), a.attributes.c_str(),
      target.NumCoeffs(raw.sh_degree), a.hidden, a.crop_size,
      omp_get_max_threads());

  const auto rasterizer = MakeRasterizer(parser.device());
  const auto t0 = std::chrono::steady_clock::now();
  if (a.iterations > 0) {
    TrainConcatEncoder(options, *in.views, in.train_views, raw,
                       in.decoder.get(), rasterizer.get(), &encoder);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  const GaussianModel marked = encoder.Apply(raw, in.message);
  WritePly(a.output_path, marked, in.ply.layout);

  const ExtractionResult before =
      Decode(*rasterizer, raw, *in.views, check_views, *in.decoder, in.message,
             options.background);
  const ExtractionResult after =
      Decode(*rasterizer, marked, *in.views, check_views, *in.decoder,
             in.message, options.background);
  const Fidelity fidelity = MeasureFidelity(*rasterizer, raw, marked, *in.views,
                                            check_views, options.background);
  std::printf("concat_embed: %lld iterations in %s\n",
              static_cast<long long>(a.iterations),
              FormatDuration(seconds).c_str());
  std::printf(
      "concat_embed: check views (%zu): BER %.2f%% -> %.2f%% (mean logits); "
      "PSNR vs ground truth %.2f -> %.2f dB, vs raw %.2f dB\n",
      check_views.size(), 100 * before.ber, 100 * after.ber,
      fidelity.raw_psnr_vs_truth, fidelity.psnr_vs_truth, fidelity.psnr_vs_raw);
  std::printf("concat_embed: wrote %s\n", a.output_path.c_str());
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(concat_embed,
                "CONCAT + 3DGS baseline: an explicit encoder writes the "
                "message into the SH coefficients",
                watergs::RunConcatEmbed);
