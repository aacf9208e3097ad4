// Gathers an ownership report's evidence (ownership_report.h) from models in
// memory: the claim and the control read from the evaluation, the views shown
// in full rendered again, suspect copies read on the same cameras, the files'
// checksums, and the watergs commands that reproduce each figure. Shared by
// `watergs report`, `embed --report` and `eval --report`.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"
#include "plugin/ownership_report.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/evaluation.h"

namespace watergs {

// How the evidence was asked for: the files and options as the user typed
// them, repeated in the reproducing commands.
struct ReportRequest {
  std::string raw_path, watermarked_path, decoder_path;
  // Suspect copies (read on the same cameras as the claim).
  std::vector<std::string> suspect_paths;
  // The claimed message as typed.
  std::string message_text;
  // --key as typed ("" unkeyed; file:PATH or the key itself).
  std::string key_option;
  // Workspace options as given (workspace, sparse path, downscale).
  WorkspaceOptions workspace;
  // --background as typed.
  std::string background = "0,0,0";
  // Views shown in full, spread evenly over the evaluated ones.
  int show_views = 3;
  // "watergs 1.2.3".
  std::string generator;
  // Shown first under "Reproduce" (e.g. the command as run).
  std::vector<ReportCommand> commands;
  // The claim is read as the owner (each view minus the raw model's, the
  // reading embed optimises by default); false: blind, the decoder alone.
  bool owner_reading = true;
};

// The options `extract` needs to read exactly `views` (indices into the
// workspace's `num_views` cameras): "" for all of them, "--max_views N" for
// extract's even spread of N; nullopt for another selection.
std::optional<std::string> ExtractViewsOption(const std::vector<size_t>& views,
                                              size_t num_views);

// " --message M" and, when keyed, " --key K" as typed, shell-quoted: the
// claim in the reproducing commands.
std::string ClaimOptions(const std::string& message_text,
                         const std::string& key_option);

// `arg` quoted for a POSIX shell where it needs quoting.
std::string ShellQuote(const std::string& arg);
// "watergs <argv[0]> <argv[1]> ...", quoted (argv[0] is the command name).
std::string CommandLine(int argc, char** argv);

// Size and FNV-1a of a file; throws Error naming it if unreadable.
ReportFile DescribeFile(const std::string& role, const std::string& path);

// The report for `evaluation`, the result of EvaluateWatermark on
// `eval_views` of `views` (a workspace of `workspace_views` cameras) with
// `options`. `suspects` are the models of request.suspect_paths, in order.
// Renders request.show_views views of both models again.
OwnershipReport CollectOwnershipReport(
    Rasterizer& rasterizer, const GaussianModel& raw,
    const GaussianModel& watermarked,
    const std::vector<GaussianModel>& suspects, const TrainingViews& views,
    const std::vector<size_t>& eval_views, size_t workspace_views,
    BitDecoder& decoder, const Bits& message, const EvaluationOptions& options,
    EvaluationReport evaluation, const ReportRequest& request);

}  // namespace watergs
