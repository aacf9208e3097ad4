// `watergs train_decoder`: trains the HiDDeN encoder and the universal
// watermark decoder on a folder of photos (paper, "Universal Watermark
// Decoder"); writes one weights file holding both networks. `--device cuda`
// runs the training steps on the GPU (docs/decoder_training.md).
#include <iostream>

#include "gaussian/util/error.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "watermark/decoder_training.h"

namespace {

int RunTrainDecoder(int argc, char** argv) {
  watergs::DecoderTrainingOptions options;
  std::string noise = "identity";
  double learning_rate = 1e-3;
  double image_weight = 0.7;
  double target_psnr = 0;
  double target_psnr_start = 24;
  int seed = int(options.seed);
  watergs::OptionParser parser(
      "train_decoder",
      "Trains the HiDDeN encoder/decoder pair; the decoder is WATER-GS's "
      "universal watermark decoder.");
  parser.Add("image_path", &options.image_path,
             "folder of training photos (jpg/png); required unless "
             "--validate_only");
  parser.AddRequired("output_path", &options.output_path,
                     "weights file to write (decoder + encoder)");
  parser.Add("validation_path", &options.validation_path,
             "folder of held-out photos validated after every epoch");
  parser.Add("num_bits", &options.config.num_bits, "message length L");
  parser.Add("channels", &options.config.channels,
             "hidden channels (64 in HiDDeN)");
  parser.Add("crop", &options.crop, "training crop side in pixels");
  parser.Add("validation_crop", &options.validation_crop,
             "center-crop side of held-out photos (0: whole photos)");
  parser.Add("epochs", &options.epochs, "epochs");
  parser.Add("batch_size", &options.batch_size, "crops per step");
  parser.Add("steps_per_epoch", &options.steps_per_epoch,
             "steps per epoch (0: one crop per training photo)");
  parser.Add("learning_rate", &learning_rate, "Adam learning rate");
  parser.Add("image_weight", &image_weight,
             "weight of MSE(cover, watermarked) against BCE(message)");
  parser.Add("target_psnr", &target_psnr,
             "if > 0, adapt image_weight to hold this encoder PSNR (dB)");
  parser.Add("target_psnr_start", &target_psnr_start,
             "PSNR target at step 0, ramped to --target_psnr");
  parser.Add("psnr_ramp_steps", &options.psnr_ramp_steps,
             "steps over which the PSNR target ramps (0: no ramp)");
  double accuracy_gate = 0;
  parser.Add("accuracy_gate", &accuracy_gate,
             "if > 0, the PSNR target ramps only while the running training "
             "bit accuracy is at least this (0..1)");
  parser.Add("noise", &noise,
             "noise layers sampled per step: identity,crop,dropout,resize,"
             "blur,jpeg");
  parser.AddFlag("resume", &options.resume,
                 "continue from OUTPUT_PATH.ckpt when it exists");
  parser.Add("checkpoint_every", &options.checkpoint_every,
             "steps between checkpoints");
  parser.Add("max_minutes", &options.max_minutes,
             "stop cleanly after this many minutes (0: run all epochs)");
  parser.Add("seed", &seed, "random seed");
  parser.AddFlag("allow_tf32", &options.allow_tf32,
                 "with --device cuda: let cuDNN/cuBLAS use TF32 tensor cores "
                 "(faster, ~1e-3 relative error per layer)");
  bool validate_only = false;
  parser.AddFlag("validate_only", &validate_only,
                 "only validate OUTPUT_PATH on --validation_path");
  if (!parser.Parse(argc, argv)) return 0;
  // cuda: the steps run on the GPU; checkpoints and weights are the same
  // files as on the CPU, so a run can resume on either device.
  options.device = parser.device();
  const int bits = options.config.num_bits;
  if (bits != 8 && bits != 16 && bits != 32 && bits != 48 && bits != 64)
    watergs::Fail("--num_bits must be 8, 16, 32, 48 or 64");
  if (options.crop < 16 || options.crop > 1024)
    watergs::Fail("--crop must be in [16, 1024]");
  if (options.batch_size < 1 || options.epochs < 1 ||
      options.config.channels < 1)
    watergs::Fail("--batch_size, --epochs and --channels must be positive");
  options.noise = watergs::ParseNoiseList(noise);
  options.learning_rate = float(learning_rate);
  options.image_weight = float(image_weight);
  options.target_psnr = float(target_psnr);
  options.target_psnr_start = float(target_psnr_start);
  options.accuracy_gate = float(accuracy_gate);
  options.seed = uint32_t(seed);
  if (validate_only) {
    if (options.validation_path.empty())
      watergs::Fail("--validate_only needs --validation_path");
    auto model = watergs::LoadHiddenModel(options.output_path, true);
    std::cout << watergs::FormatValidation(watergs::Validate(
                     *model, watergs::LoadPhotoFolder(options.validation_path),
                     options.validation_crop, 7))
              << "\n";
    return 0;
  }
  if (options.image_path.empty()) watergs::Fail("--image_path is required");
  watergs::TrainDecoder(options);
  std::cout << "wrote " << options.output_path << "\n";
  return 0;
}

}  // namespace

WATERGS_COMMAND(train_decoder,
                "Trains the universal watermark decoder (HiDDeN) on photos",
                RunTrainDecoder);
