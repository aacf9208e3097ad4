// Tests for training checkpoints: exact round trip, and a clear error for
// every kind of damage (truncation, flipped byte, wrong magic, version).
#include "gaussian/checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <random>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

std::string TempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_checkpoint_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

TrainingCheckpoint MakeCheckpoint() {
  TrainingCheckpoint c;
  c.iteration = 1234;
  c.active_sh_degree = 1;
  c.elapsed_seconds = 56.5;
  c.model.sh_degree = 2;
  c.model.Resize(5);
  std::mt19937 rng(1);
  std::normal_distribution<float> normal;
  for (float& v : c.model.means) v = normal(rng);
  for (float& v : c.model.sh_rest) v = normal(rng);
  for (int g = 0; g < kNumParamGroups; ++g) {
    c.adam[g].exp_avg.assign(5 * (g + 1), 0.5f * g);
    c.adam[g].exp_avg_sq.assign(5 * (g + 1), 0.25f * g);
    c.adam[g].step = 100 + g;
    c.adam[g].exp_avg_q.assign(3 * g, uint8_t(17 * g));
    c.adam[g].exp_avg_sq_shared.assign(g, 0.125f * g);
  }
  c.adam_rejected = 3;
  c.density_state = std::string("\0density\xff", 9);
  c.rng_state = "1 2 3";
  c.view_stack = {4, 0, 2};
  c.run_signature = "{\"seed\":1}";
  return c;
}

std::string Bytes(const std::string& path) {
  const auto b = ReadFileBytes(path);
  return std::string(b.begin(), b.end());
}

void ExpectReadFails(const std::string& path, const std::string& bytes,
                     const std::string& message) {
  AtomicWriteFile(path, bytes);
  try {
    ReadCheckpoint(path);
    ADD_FAILURE() << "no error for " << message;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
  }
}

TEST(Checkpoint, RoundTripIsExact) {
  const std::string path = TempPath("round_trip.ckpt");
  const TrainingCheckpoint c = MakeCheckpoint();
  WriteCheckpoint(path, c);
  const TrainingCheckpoint r = ReadCheckpoint(path);
  EXPECT_EQ(r.iteration, c.iteration);
  EXPECT_EQ(r.active_sh_degree, c.active_sh_degree);
  EXPECT_EQ(r.elapsed_seconds, c.elapsed_seconds);
  EXPECT_EQ(r.model.sh_degree, 2);
  EXPECT_EQ(r.model.means, c.model.means);
  EXPECT_EQ(r.model.sh_rest, c.model.sh_rest);
  EXPECT_EQ(r.model.quats, c.model.quats);
  for (int g = 0; g < kNumParamGroups; ++g) {
    EXPECT_EQ(r.adam[g].exp_avg, c.adam[g].exp_avg);
    EXPECT_EQ(r.adam[g].exp_avg_sq, c.adam[g].exp_avg_sq);
    EXPECT_EQ(r.adam[g].step, c.adam[g].step);
    EXPECT_EQ(r.adam[g].exp_avg_q, c.adam[g].exp_avg_q);
    EXPECT_EQ(r.adam[g].exp_avg_sq_shared, c.adam[g].exp_avg_sq_shared);
  }
  EXPECT_EQ(r.adam_rejected, 3);
  EXPECT_EQ(r.density_state, c.density_state);
  EXPECT_EQ(r.rng_state, c.rng_state);
  EXPECT_EQ(r.view_stack, c.view_stack);
  EXPECT_EQ(r.run_signature, c.run_signature);
}

TEST(Checkpoint, DamageIsReportedClearly) {
  const std::string good = TempPath("good.ckpt");
  WriteCheckpoint(good, MakeCheckpoint());
  const std::string bytes = Bytes(good);
  const std::string bad = TempPath("bad.ckpt");
  ExpectReadFails(bad, bytes.substr(0, bytes.size() / 2), "checksum");
  std::string flipped = bytes;
  flipped[bytes.size() / 3] ^= 0x10;
  ExpectReadFails(bad, flipped, "checksum");
  ExpectReadFails(bad, "PLY\n" + bytes.substr(4), "not a watergs");
  ExpectReadFails(bad, "", "not a watergs");
  // Another version with a valid checksum.
  std::string other = bytes.substr(0, bytes.size() - 8);
  const uint32_t version = kCheckpointVersion + 1;
  std::memcpy(&other[8], &version, 4);
  const uint64_t sum = Fnv1a64(other.data(), other.size());
  other.append(reinterpret_cast<const char*>(&sum), 8);
  ExpectReadFails(bad, other, "version");
  EXPECT_THROW(ReadCheckpoint(TempPath("missing.ckpt")), Error);
}

TEST(Checkpoint, Fnv1aKnownValues) {
  // Published FNV-1a 64 test vectors.
  EXPECT_EQ(Fnv1a64("", 0), 0xcbf29ce484222325ull);
  EXPECT_EQ(Fnv1a64("a", 1), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a64("foobar", 6), 0x85944171f73967e8ull);
}

}  // namespace
}  // namespace watergs
