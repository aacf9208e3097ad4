// Resumable training state: parameters, Adam moments, density-control state,
// iteration and RNG, in a versioned binary file with a checksum, written
// atomically. Resuming from it continues to the same result as an
// uninterrupted run (same seed and thread count).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "gaussian/adam.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/util/file_util.h"

namespace watergs {

// Format version written by WriteCheckpoint; older/newer ones are refused.
// Version 2 added bfloat16 Adam moments; version 1 files are still read.
constexpr uint32_t kCheckpointVersion = 2;

struct TrainingCheckpoint {
  // Last completed iteration (1-based; 0 = nothing trained yet).
  int64_t iteration = 0;
  // SH degree in use at that iteration.
  int active_sh_degree = 0;
  // Training seconds spent so far (for the log's time column).
  double elapsed_seconds = 0;
  // The Gaussians.
  GaussianModel model;
  // Adam moments and step counts per group (ParamGroup order).
  std::array<AdamGroupState, kNumParamGroups> adam;
  // Non-finite gradient values Adam has rejected so far.
  int64_t adam_rejected = 0;
  // DensityStrategy::SaveState bytes.
  std::string density_state;
  // The trainer's view-order RNG (std::mt19937_64 text form) and the views
  // left in the current epoch.
  std::string rng_state;
  std::vector<uint32_t> view_stack;
  // Options that must match to resume (JSON text, compared verbatim).
  std::string run_signature;
};

// Writes `checkpoint` to `path` atomically (Error on failure).
void WriteCheckpoint(const std::string& path,
                     const TrainingCheckpoint& checkpoint);

// Reads a checkpoint; throws Error("<path>: ...") if missing, not a
// checkpoint, of another version, truncated or failing its checksum.
TrainingCheckpoint ReadCheckpoint(const std::string& path);

}  // namespace watergs
