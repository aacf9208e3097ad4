// `watergs pipeline`: a folder of photos to a watermarked splat and its
// ownership report in one command: reconstruct, train (held-out views kept
// aside), embed with the recommended defaults and --report. Each stage runs
// the registered command in this process (so the Python module runs it the
// same way), leaves a marker holding its arguments, and is kept on a second
// run; train and embed resume from their checkpoints.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/text_util.h"
#include "plugin/colmap_workflow.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "plugin/report_evidence.h"
#include "watermark/bit_decoder.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// One stage: args[0] is the command's name.
using StageArgs = std::vector<std::string>;

// "watergs train --a 1 ...", shell-quoted: what a marker holds.
std::string Joined(const StageArgs& args) {
  std::string line = "watergs";
  for (const std::string& a : args) line += " " + ShellQuote(a);
  return line + "\n";
}

// Runs the registered command args[0] on `args`; its own Error on failure.
void RunInProcess(const StageArgs& args) {
  const auto found = CommandRegistry().find(args[0]);
  if (found == CommandRegistry().end()) {
    Fail("pipeline: no command " + args[0]);
  }
  StageArgs copy = args;
  std::vector<char*> argv;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int code = found->second.run(int(copy.size()), argv.data());
  if (code != 0) {
    Fail("pipeline: " + args[0] + " exited with code " + std::to_string(code));
  }
}

struct PipelineArgs {
  std::string image_path, workspace_path, output_path, decoder, message, key,
      train_args, embed_args;
  // "cpu" or "cuda" when --device was given (else each stage's default).
  std::string device;
  int downscale = 2, iterations = 7000, num_threads = 0;
};

// The three stages' arguments for `a`.
std::vector<StageArgs> PipelineStages(const PipelineArgs& a,
                                      const fs::path& out) {
  // An existing workspace is used as it is (no reconstruct stage).
  const bool reconstruct = a.workspace_path.empty();
  const std::string ws = reconstruct ? (out / "workspace").string()
                                     : fs::absolute(a.workspace_path).string();
  const std::string threads = std::to_string(a.num_threads);
  StageArgs common = {"--workspace_path", ws,
                      "--downscale",      std::to_string(a.downscale),
                      "--num_threads",    threads};
  if (!reconstruct && !a.image_path.empty()) {
    common.insert(common.end(),
                  {"--image_path", fs::absolute(a.image_path).string()});
  }
  std::vector<StageArgs> stages = {
      {"reconstruct", "--image_path",
       reconstruct ? fs::absolute(a.image_path).string() : "",
       "--workspace_path", ws, "--num_threads", threads},
      {"train", "--output_path", (out / "train").string(), "--split", "train",
       "--iterations", std::to_string(a.iterations), "--test_iterations",
       std::to_string(a.iterations), "--densify_until_iter",
       std::to_string(a.iterations / 2), "--checkpoint_every", "500"},
      {"embed", "--input_path", (out / "train" / "point_cloud.ply").string(),
       "--decoder", a.decoder, "--message", a.message, "--output_path",
       (out / "watermarked.ply").string(), "--split", "train",
       "--checkpoint_every", "250", "--report",
       (out / "report.html").string()}};
  if (!a.key.empty()) stages[2].insert(stages[2].end(), {"--key", a.key});
  if (!a.device.empty()) {
    for (size_t k = 1; k < 3; ++k) {
      stages[k].insert(stages[k].end(), {"--device", a.device});
    }
  }
  for (size_t k = 1; k < 3; ++k) {
    stages[k].insert(stages[k].end(), common.begin(), common.end());
    for (const std::string& w :
         SplitList(k == 1 ? a.train_args : a.embed_args, ' ')) {
      stages[k].push_back(w);
    }
  }
  if (!reconstruct) stages.erase(stages.begin());
  return stages;
}

int RunPipeline(int argc, char** argv) {
  PipelineArgs a;
  OptionParser parser(
      "pipeline",
      "From a folder of photos to a watermarked 3DGS model and its ownership "
      "report: reconstruct (COLMAP), train with every 8th view held out, "
      "embed with the recommended defaults, the held-out cost and the "
      "report. Writes OUT/workspace, OUT/train, OUT/watermarked.ply and "
      "OUT/report.html; a second run keeps the stages done and resumes the "
      "one that was stopped.");
  parser.Add("image_path", &a.image_path,
             "Folder of photos (reconstructed with COLMAP first); with "
             "--workspace_path, that workspace's image folder if not "
             "<workspace>/images");
  parser.Add("workspace_path", &a.workspace_path,
             "An existing COLMAP workspace (sparse/0 and images/): the "
             "reconstruct stage is skipped");
  a.decoder = ShippedDecoderPath();
  parser.Add("decoder", &a.decoder, kDecoderHelp);
  parser.AddRequired("message", &a.message, "The owner's message");
  parser.Add("key", &a.key, "The owner's key (see embed --key)");
  parser.AddRequired("output_path", &a.output_path, "Output folder");
  parser.Add("downscale", &a.downscale, "Image downscale for train and embed");
  parser.Add("iterations", &a.iterations, "Training iterations");
  parser.Add("train_args", &a.train_args,
             "More train options, space-separated");
  parser.Add("embed_args", &a.embed_args,
             "More embed options, space-separated");
  parser.Add("num_threads", &a.num_threads, "Threads (0 = all cores)");
  if (!parser.Parse(argc, argv)) return 0;
  if (parser.Given("device")) a.device = DeviceName(parser.device());
  if (a.iterations < 1) Fail("pipeline: --iterations must be >= 1");
  if (a.image_path.empty() && a.workspace_path.empty()) {
    Fail(
        "pipeline: give --image_path (a folder of photos) or "
        "--workspace_path (an existing COLMAP workspace)");
  }
  if (!a.image_path.empty() && !fs::is_directory(a.image_path)) {
    FailAt(a.image_path, "not a folder of photos");
  }
  if (!a.workspace_path.empty() && !fs::is_directory(a.workspace_path)) {
    FailAt(a.workspace_path, "not a COLMAP workspace folder");
  }
  if (!fs::is_regular_file(a.decoder)) FailAt(a.decoder, "no decoder file");
  const fs::path out = fs::absolute(a.output_path);
  const std::vector<StageArgs> stages = PipelineStages(a, out);
  // Stages done before must have run these arguments.
  std::vector<bool> done(stages.size(), false);
  for (size_t k = 0; k < stages.size(); ++k) {
    const fs::path marker = out / ".pipeline" / (stages[k][0] + ".done");
    if (!fs::exists(marker)) continue;
    const std::vector<uint8_t> bytes = ReadFileBytes(marker.string());
    if (std::string(bytes.begin(), bytes.end()) != Joined(stages[k])) {
      FailAt(marker.string(),
             "was done with other settings: use another --output_path, or "
             "remove the stage's output and marker to redo it");
    }
    done[k] = true;
  }
  fs::create_directories(out / ".pipeline");
  const auto begin = std::chrono::steady_clock::now();
  for (size_t k = 0; k < stages.size(); ++k) {
    const std::string& name = stages[k][0];
    if (done[k]) {
      std::printf("pipeline: %zu/%zu %s done before, kept\n", k + 1,
                  stages.size(), name.c_str());
      continue;
    }
    StageArgs args = stages[k];
    // A stopped run continues from its checkpoint.
    if (name == "train" && fs::exists(out / "train" / "checkpoint.ckpt")) {
      args.push_back("--resume");
    } else if (name == "train" && fs::exists(out / "train")) {
      args.push_back("--overwrite");  // stopped before its first checkpoint
    } else if (name == "embed" &&
               fs::exists((out / "watermarked.ply.ckpt").string())) {
      args.push_back("--resume");
    }
    std::printf("pipeline: %zu/%zu %s\n", k + 1, stages.size(), name.c_str());
    std::fflush(stdout);
    const auto start = std::chrono::steady_clock::now();
    RunInProcess(args);
    AtomicWriteFile((out / ".pipeline" / (name + ".done")).string(),
                    Joined(stages[k]));
    std::printf(
        "pipeline: %s done in %.0f s\n", name.c_str(),
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
            .count());
    const fs::path train_report = out / "train" / "report.json";
    if (name == "train" && fs::exists(train_report)) {
      const std::vector<uint8_t> bytes = ReadFileBytes(train_report.string());
      std::fputs(
          OutlierViewWarning(std::string(bytes.begin(), bytes.end())).c_str(),
          stdout);
    }
  }
  std::printf(
      "pipeline: %s and %s written (%.0f s this run)\n",
      (out / "watermarked.ply").c_str(), (out / "report.html").c_str(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin)
          .count());
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(pipeline,
                "Photos to a watermarked splat and its ownership report",
                watergs::RunPipeline);
