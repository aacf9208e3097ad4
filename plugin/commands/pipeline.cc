// `watergs pipeline`: a folder of photos to a watermarked splat and its
// ownership report in one command: reconstruct, train (held-out views kept
// aside), embed with the recommended defaults and --report. Each stage runs
// this same binary's command, leaves a marker holding that command, and is
// kept on a second run; train and embed resume from their checkpoints.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "gaussian/error.h"
#include "gaussian/file_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "plugin/report_evidence.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

struct PipelineStage {
  std::string name, command;
};

// This binary, to run the stages' commands.
std::string SelfPath() {
  std::error_code error;
  const fs::path self = fs::read_symlink("/proc/self/exe", error);
  if (error) Fail("pipeline: cannot find its own binary (/proc/self/exe)");
  return self.string();
}

int RunPipeline(int argc, char** argv) {
  std::string image_path, output_path, decoder, message, key, train_args,
      embed_args;
  int downscale = 2, iterations = 7000, num_threads = 0;
  OptionParser parser(
      "pipeline",
      "From a folder of photos to a watermarked 3DGS model and its ownership "
      "report: reconstruct (COLMAP), train with every 8th view held out, "
      "embed with the recommended defaults, the held-out cost and the "
      "report. Writes OUT/workspace, OUT/train, OUT/watermarked.ply and "
      "OUT/report.html; a second run keeps the stages done and resumes the "
      "one that was stopped.");
  parser.AddRequired("image_path", &image_path, "Folder of photos");
  parser.AddRequired("decoder", &decoder, "Decoder weights file");
  parser.AddRequired("message", &message, "The owner's message");
  parser.Add("key", &key, "The owner's key (see embed --key)");
  parser.AddRequired("output_path", &output_path, "Output folder");
  parser.Add("downscale", &downscale, "Image downscale for train and embed");
  parser.Add("iterations", &iterations, "Training iterations");
  parser.Add("train_args", &train_args, "More options for train");
  parser.Add("embed_args", &embed_args, "More options for embed");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  if (!parser.Parse(argc, argv)) return 0;
  if (iterations < 1) Fail("pipeline: --iterations must be >= 1");
  if (!fs::is_directory(image_path)) {
    FailAt(image_path, "not a folder of photos");
  }
  if (!fs::is_regular_file(decoder)) FailAt(decoder, "no decoder file");
  const fs::path out = fs::absolute(output_path);
  const std::string self = ShellQuote(SelfPath());
  const std::string ws = ShellQuote((out / "workspace").string());
  const std::string threads = " --num_threads " + std::to_string(num_threads);
  const std::string common = " --workspace_path " + ws + " --downscale " +
                             std::to_string(downscale) + threads;
  const std::string raw = (out / "train" / "point_cloud.ply").string();
  const std::string marked = (out / "watermarked.ply").string();
  std::vector<PipelineStage> stages = {
      {"reconstruct", self + " reconstruct --image_path " +
                          ShellQuote(fs::absolute(image_path).string()) +
                          " --workspace_path " + ws + threads},
      {"train", self + " train" + common + " --output_path " +
                    ShellQuote((out / "train").string()) +
                    " --eval --iterations " + std::to_string(iterations) +
                    " --test_iterations " + std::to_string(iterations) +
                    " --checkpoint_every 500 " + train_args},
      {"embed", self + " embed" + common + " --input_path " + ShellQuote(raw) +
                    " --decoder " + ShellQuote(decoder) +
                    ClaimOptions(message, key) + " --output_path " +
                    ShellQuote(marked) + " --eval --checkpoint_every 250 " +
                    "--report " + ShellQuote((out / "report.html").string()) +
                    " " + embed_args}};
  fs::create_directories(out / ".pipeline");
  const auto begin = std::chrono::steady_clock::now();
  for (size_t k = 0; k < stages.size(); ++k) {
    const PipelineStage& stage = stages[k];
    const fs::path marker = out / ".pipeline" / (stage.name + ".done");
    if (fs::exists(marker)) {
      const std::vector<uint8_t> bytes = ReadFileBytes(marker.string());
      if (std::string(bytes.begin(), bytes.end()) != stage.command + "\n") {
        FailAt(marker.string(),
               "was done with other settings: use another "
               "--output_path, or remove the stage's output "
               "and marker to redo it");
      }
      std::printf("pipeline: %zu/%zu %s done before, kept\n", k + 1,
                  stages.size(), stage.name.c_str());
      continue;
    }
    std::string command = stage.command;
    // A stopped run continues from its checkpoint.
    if (stage.name == "train" &&
        fs::exists(out / "train" / "checkpoint.ckpt")) {
      command += " --resume";
    } else if (stage.name == "train" && fs::exists(out / "train")) {
      command += " --overwrite";  // stopped before its first checkpoint
    } else if (stage.name == "embed" && fs::exists(marked + ".ckpt")) {
      command += " --resume";
    }
    std::printf("pipeline: %zu/%zu %s\n", k + 1, stages.size(),
                stage.name.c_str());
    std::fflush(stdout);
    const auto start = std::chrono::steady_clock::now();
    if (std::system(command.c_str()) != 0) {
      Fail("pipeline: stage " + stage.name +
           " failed (its error above); run "
           "the same pipeline command again to resume");
    }
    AtomicWriteFile(marker.string(), stage.command + "\n");
    std::printf(
        "pipeline: %s done in %.0f s\n", stage.name.c_str(),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count());
  }
  std::printf(
      "pipeline: %s and %s written (%.0f s this run)\n", marked.c_str(),
      (out / "report.html").c_str(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin)
          .count());
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(pipeline,
                "Photos to a watermarked splat and its ownership report",
                watergs::RunPipeline);
