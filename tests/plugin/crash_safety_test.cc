// Crash safety of `watergs train` and `watergs embed`: each is killed with
// SIGKILL at pseudo-random moments (fixed seed); after every kill each output
// must be absent or a complete file (parsed) and checkpoints never go back;
// `--resume` then finishes with output bit-identical to an uninterrupted run
// with the same seed and thread count. Runs on a small synthetic workspace
// (8 views of 64x48, ~200 points: the demo scene's 8500 Gaussians cost
// ~0.1 s per iteration on two loaded cores) with short runs and frequent
// checkpoints, so that kills often land inside a write.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <thread>

#include "gaussian/checkpoint.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/point_init.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// WS/sparse/0 (8 pinhole views, 64x48) and rendered WS/images.
std::string MakeWorkspace(const testing::TempDir& dir) {
  testing::SyntheticModelOptions options;
  options.num_images = 8;
  options.num_points = 200;
  return testing::MakeRenderedWorkspace(dir / "ws", options);
}

// Starts `watergs args...` with stdout and stderr going to `output_path`;
// returns its pid.
pid_t Spawn(const std::vector<std::string>& args,
            const std::string& output_path = "/dev/null") {
  std::vector<std::string> argv = {testing::WatergsBin()};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> raw;
  for (std::string& a : argv) raw.push_back(a.data());
  raw.push_back(nullptr);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    const int fd =
        open(output_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    execv(raw[0], raw.data());
    _exit(127);
  }
  return pid;
}

// Waits for `pid`; its exit code (-signal if killed).
int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

// Runs to completion (fails the test on exit != 0); returns what it printed.
std::string RunToEnd(const std::vector<std::string>& args) {
  const std::string output_path =
      fs::temp_directory_path() / ("watergs_crash_" + std::to_string(getpid()));
  const int code = Wait(Spawn(args, output_path));
  const std::vector<uint8_t> bytes = ReadFileBytes(output_path);
  fs::remove(output_path);
  const std::string output(bytes.begin(), bytes.end());
  EXPECT_EQ(code, 0) << "watergs " << args[0] << " failed: " << output;
  return output;
}

// The number after `label` in `text` (0 if absent).
double NumberAfter(const std::string& text, const std::string& label) {
  const size_t at = text.find(label);
  EXPECT_NE(at, std::string::npos) << label << " in " << text;
  return at == std::string::npos ? 0
                                 : std::atof(text.c_str() + at + label.size());
}

std::vector<std::string> Concat(std::vector<std::string> a,
                                const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// The "iteration"-keyed lines of a JSON-lines log without the wall-clock
// column; every line must parse and iterations must increase.
std::vector<nlohmann::json> ReadLog(const std::string& path) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
    EXPECT_FALSE(j.is_discarded()) << path << ": partial line `" << line << "`";
    if (j.is_discarded()) continue;
    if (!lines.empty()) {
      EXPECT_GT(j["iteration"], lines.back()["iteration"]) << path;
    }
    j.erase("seconds");
    lines.push_back(j);
  }
  return lines;
}

// What the outputs looked like after the previous kill.
struct Seen {
  // Iteration of the checkpoint (-1 while absent).
  int64_t checkpoint_iteration = -1;
  // Temporaries a kill left behind (allowed until the next write of their
  // output: SIGKILL gives no chance to remove them; the outputs themselves
  // are never partial).
  int temporaries = 0;
};

// Every file in `dir` is a temporary or a complete output: PLYs and
// checkpoints parse (the checkpoint's checksum covers all of it), JSON
// parses, log lines are whole; checkpoints never go back.
void CheckOutputs(const std::string& dir, int64_t checkpoint_every,
                  Seen* seen) {
  if (!fs::exists(dir)) return;
  seen->temporaries = 0;
  bool has_checkpoint = false;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string path = entry.path().string();
    const std::string name = entry.path().filename().string();
    SCOPED_TRACE(name);
    if (name.find(".tmp.") != std::string::npos) {
      ++seen->temporaries;
    } else if (name.ends_with(".ckpt")) {
      has_checkpoint = true;
      const TrainingCheckpoint c = ReadCheckpoint(path);
      EXPECT_EQ(c.iteration % checkpoint_every, 0);
      EXPECT_GE(c.iteration, seen->checkpoint_iteration);
      seen->checkpoint_iteration = c.iteration;
    } else if (name.ends_with(".ply")) {
      EXPECT_GT(ReadPly(path).model.size(), 0u);
    } else if (name.ends_with(".jsonl")) {
      ReadLog(path);
    } else if (name.ends_with(".json")) {
      std::ifstream in(path);
      EXPECT_FALSE(nlohmann::json::parse(in, nullptr, false).is_discarded());
    } else {
      ADD_FAILURE() << "unexpected output " << path;
    }
  }
  // A checkpoint, once written, is only ever replaced.
  if (seen->checkpoint_iteration >= 0) {
    EXPECT_TRUE(has_checkpoint);
  }
}

// Iteration of the checkpoint at `path` (-1 if absent), from its header:
// magic(8) version(4) iteration(8). Replaced by rename, so never partial.
int64_t CheckpointIteration(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char header[20];
  if (!in.read(header, sizeof(header))) return -1;
  int64_t iteration = 0;
  std::memcpy(&iteration, header + 12, sizeof(iteration));
  return iteration;
}

// Kills `args` (plus --resume once a checkpoint exists) up to `kills` times
// and checks the outputs after each kill, then resumes it to the end. Kill k
// comes once the checkpoint has reached targets[k] (distinct multiples of
// the checkpoint period drawn from `seed`, increasing; 0 = from the start,
// so loading and the first period are hit too) plus a random fraction of one
// checkpoint period (timed from the reference run's seconds per iteration),
// and at the latest when the next checkpoint appears: the reference's rate
// can be far off on a loaded machine, and a kill timed only by it found the
// run finished. Moments spread over the run, writes included, every attempt
// makes progress, and every attempt is killed well before the end.
void KillAndResume(const std::vector<std::string>& args,
                   const std::string& out_dir, const std::string& checkpoint,
                   int64_t iterations, int64_t checkpoint_every,
                   double seconds_per_iteration, int kills, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<int64_t> targets;
  for (int64_t t = 0; t + checkpoint_every < iterations;
       t += checkpoint_every) {
    targets.push_back(t);
  }
  std::shuffle(targets.begin(), targets.end(), rng);
  targets.resize(std::min<size_t>(kills, targets.size()));
  std::sort(targets.begin(), targets.end());
  const double period = seconds_per_iteration * checkpoint_every;
  std::uniform_real_distribution<double> fraction(0.0, 1.0);
  Seen seen;
  int killed = 0;
  for (int64_t target : targets) {
    const bool resume = fs::exists(checkpoint);
    const pid_t pid = Spawn(resume ? Concat(args, {"--resume"}) : args);
    const double extra = fraction(rng) * period;
    int status = 0;
    pid_t done = 0;
    std::optional<Clock::time_point> kill_at;
    while ((done = waitpid(pid, &status, WNOHANG)) == 0) {
      const int64_t reached =
          std::max<int64_t>(0, CheckpointIteration(checkpoint));
      if (!kill_at && reached >= target) {
        kill_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(extra));
      }
      if (kill_at &&
          (Clock::now() >= *kill_at || reached >= target + checkpoint_every)) {
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (done == 0) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      ++killed;
    } else {
      // Finished before the kill: it must have succeeded.
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    CheckOutputs(out_dir, checkpoint_every, &seen);
    if (done != 0) break;
  }
  // Targets end a period before the last checkpoint, so a run can only
  // finish before its kill if the test itself is starved for that long.
  EXPECT_GE(killed, 1);
  RunToEnd(fs::exists(checkpoint) ? Concat(args, {"--resume"}) : args);
  const int left_by_kills = seen.temporaries;
  CheckOutputs(out_dir, checkpoint_every, &seen);
  // The final run rewrote every output, removing the kills' temporaries.
  EXPECT_EQ(seen.temporaries, 0);
  std::printf(
      "[ killed %d times (checkpoints at %s, period %.0f ms), resumed; %d "
      "temporaries left by kills ]\n",
      killed, ::testing::PrintToString(targets).c_str(), 1e3 * period,
      left_by_kills);
}

std::vector<uint8_t> Bytes(const std::string& path) {
  return ReadFileBytes(path);
}

TEST(CrashSafety, KilledTrainAndEmbedResumeToTheUninterruptedResult) {
  testing::TempDir dir("crash_safety");
  const std::string ws = MakeWorkspace(dir);
  constexpr int64_t kTrainEvery = 20, kEmbedEvery = 10;
  const auto train_args = [&](const std::string& out) {
    return std::vector<std::string>{
        "train", "--workspace_path", ws, "--output_path", out, "--iterations",
        "160", "--checkpoint_every", std::to_string(kTrainEvery), "--sh_degree",
        "1", "--seed", "7", "--num_threads", "2", "--log_every", "5",
        // Density control at iteration 100 so that a resume must restore
        // its statistics to clone, split and prune the same Gaussians.
        "--densify_from_iter", "50", "--densify_until_iter", "160"};
  };
  const std::string ref = dir / "train_ref", out = dir / "train_killed";
  // "train: 160 iterations in 1.2s (133.3 it/s), ..."
  const double train_it_per_s = NumberAfter(RunToEnd(train_args(ref)), "s (");
  KillAndResume(train_args(out), out, out + "/checkpoint.ckpt", 160,
                kTrainEvery, 1 / train_it_per_s, 4, 20261121);
  EXPECT_EQ(Bytes(out + "/point_cloud.ply"), Bytes(ref + "/point_cloud.ply"));
  EXPECT_EQ(Bytes(out + "/cameras.json"), Bytes(ref + "/cameras.json"));
  // Every log line survives the kills, with the same losses; density
  // control did change the model.
  const std::vector<nlohmann::json> log = ReadLog(ref + "/train_log.jsonl");
  ASSERT_EQ(log.size(), 33u);  // iterations 1, 5, 10, ..., 160
  EXPECT_NE(log.front()["num_gaussians"], log.back()["num_gaussians"]);
  EXPECT_EQ(ReadLog(out + "/train_log.jsonl"), log);

  // Embed into the trained model with a tiny random decoder.
  const std::string decoder = testing::WriteTinyDecoder(dir / "decoder.bin");
  const auto embed_args = [&](const std::string& out_ply) {
    return std::vector<std::string>{"embed",
                                    "--input_path",
                                    ref + "/point_cloud.ply",
                                    "--workspace_path",
                                    ws,
                                    "--decoder",
                                    decoder,
                                    "--message",
                                    "hex:a5c3",
                                    "--output_path",
                                    out_ply,
                                    "--iterations",
                                    "80",
                                    "--crop_size",
                                    "32",
                                    "--distortions",
                                    "identity,gn:0.01,dropout:0.1",
                                    "--check_every",
                                    "1000",
                                    "--check_views",
                                    "1",
                                    "--patience",
                                    "0",
                                    "--seed",
                                    "5",
                                    "--num_threads",
                                    "2",
                                    "--checkpoint_every",
                                    std::to_string(kEmbedEvery)};
  };
  const std::string embed_ref = dir / "embed_ref", embed_out = dir / "embed";
  CreateDirectories(embed_ref);
  CreateDirectories(embed_out);
  // "embed: per iteration 5.1 ms = ..."
  const double embed_ms_per_it = NumberAfter(
      RunToEnd(embed_args(embed_ref + "/wm.ply")), "per iteration ");
  KillAndResume(embed_args(embed_out + "/wm.ply"), embed_out,
                embed_out + "/wm.ply.ckpt", 80, kEmbedEvery,
                embed_ms_per_it / 1000, 4, 7);
  EXPECT_EQ(Bytes(embed_out + "/wm.ply"), Bytes(embed_ref + "/wm.ply"));
}

}  // namespace
}  // namespace watergs
