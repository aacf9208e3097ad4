// Malformed decoder-weights files beyond network_file_test.cc: every
// byte-prefix truncation (so every section and tensor boundary), a tensor
// whose shape would need a petabyte, and NaN weights, each refused by the
// decoder loader with one line naming the file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "watermark/decoder.h"
#include "watermark/hidden_model.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

class MalformedWeights : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("watergs_malformed_weights_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    HiddenConfig config;
    config.num_bits = 4;
    config.channels = 2;
    config.encoder_blocks = 1;
    config.decoder_blocks = 1;
    HiddenModel model(config, false, 5);
    file_ = HiddenModelToFile(model, false);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& bytes) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return path;
  }
  // Decoder::Load(path) throws one line starting with the path and
  // containing `problem`.
  static void ExpectRefused(const std::string& path,
                            const std::string& problem) {
    try {
      Decoder::Load(path);
      ADD_FAILURE() << "accepted; expected " << problem;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(problem), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  // Serialized bytes with the checksum recomputed after `edit`.
  template <typename Edit>
  std::string Resigned(Edit edit) const {
    std::string bytes = SerializeNetworkFile(file_);
    edit(&bytes);
    const uint64_t sum = Fnv1a64(reinterpret_cast<const uint8_t*>(bytes.data()),
                                 bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
    return bytes;
  }

  fs::path dir_;
  NetworkFile file_;
};

TEST_F(MalformedWeights, TruncatedAtEveryByte) {
  const std::string bytes = SerializeNetworkFile(file_);
  ASSERT_LT(bytes.size(), 20000u);
  for (size_t keep = 0; keep < bytes.size(); ++keep) {
    SCOPED_TRACE(keep);
    ExpectRefused(Write("cut.bin", bytes.substr(0, keep)), "");
  }
  EXPECT_NO_THROW(Decoder::Load(Write("whole.bin", bytes)));
}

TEST_F(MalformedWeights, TensorShapeNeedingAPetabyteIsRefusedUnallocated) {
  // The first tensor's first two dims become 2^24 x 2^24 (2^48 floats).
  const std::string name = file_.tensors[0].name;
  const std::string path = Write(
      "huge.bin", Resigned([&](std::string* b) {
        const size_t at = b->find(name) + name.size() + 4;  // past the rank
        const int32_t dim = 1 << 24;
        std::memcpy(b->data() + at, &dim, 4);
        std::memcpy(b->data() + at + 4, &dim, 4);
      }));
  ExpectRefused(path, "truncated network file (tensor " + name + ")");
}

TEST_F(MalformedWeights, NonFiniteWeightsAreRefused) {
  for (float bad : {std::numeric_limits<float>::quiet_NaN(),
                    std::numeric_limits<float>::infinity()}) {
    NetworkFile file = file_;
    file.tensors.back().values[0] = bad;
    const std::string path = (dir_ / "nan.bin").string();
    WriteNetworkFile(path, file);
    ExpectRefused(path, "non-finite value in tensor");
  }
}

// Version 2 files end with the standard FNV-1a 64 of the bytes before it
// (written out here: offset basis 14695981039346656037, prime 1099511628211);
// version 1 files, written before the basis was corrected, with the basis
// one digit short, and still read; either checksum under the other version
// is refused, and so is an unknown version.
TEST_F(MalformedWeights, ChecksumFollowsTheFileVersion) {
  auto fnv = [](const std::string& bytes, uint64_t basis) {
    uint64_t hash = basis;
    for (size_t i = 0; i + 8 < bytes.size(); ++i) {
      hash ^= uint8_t(bytes[i]);
      hash *= 1099511628211ull;
    }
    return hash;
  };
  constexpr uint64_t kStandard = 14695981039346656037ull;
  constexpr uint64_t kLegacy = 1469598103934665603ull;
  const size_t version_at = 8;  // after the 8-byte magic
  auto with = [&](uint32_t version, uint64_t basis) {
    std::string bytes = SerializeNetworkFile(file_);
    std::memcpy(bytes.data() + version_at, &version, 4);
    const uint64_t sum = fnv(bytes, basis);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
    return bytes;
  };
  const std::string written = SerializeNetworkFile(file_);
  uint32_t version = 0;
  std::memcpy(&version, written.data() + version_at, 4);
  EXPECT_EQ(version, 2u);
  EXPECT_EQ(written, with(2, kStandard));
  EXPECT_NO_THROW(Decoder::Load(Write("v2.bin", with(2, kStandard))));
  EXPECT_NO_THROW(Decoder::Load(Write("v1.bin", with(1, kLegacy))));
  ExpectRefused(Write("v1_standard.bin", with(1, kStandard)),
                "checksum mismatch");
  ExpectRefused(Write("v2_legacy.bin", with(2, kLegacy)), "checksum mismatch");
  ExpectRefused(Write("v3.bin", with(3, kStandard)),
                "unsupported network file version 3");
}

}  // namespace
}  // namespace watergs
