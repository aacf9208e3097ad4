// The weights file: round trip, and refusal of truncated, corrupted, foreign
// and wrong-architecture files with one-line errors naming the file.
#include "watermark/network_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "watermark/hidden_model.h"

namespace watergs {
namespace {

HiddenConfig SmallConfig(int bits) {
  HiddenConfig config;
  config.num_bits = bits;
  config.channels = 6;
  config.encoder_blocks = 2;
  config.decoder_blocks = 3;
  return config;
}

class NetworkFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("watergs_network_file_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) { return (dir_ / name).string(); }
  void WriteBytes(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary) << bytes;
  }
  // Message of the Error that loading `path` throws ("" if none).
  std::string LoadError(const std::string& path, bool need_encoder = false,
                        int bits = 0) {
    try {
      LoadHiddenModel(path, need_encoder, bits);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path dir_;
};

TEST_F(NetworkFileTest, RoundTripKeepsEveryTensorAndTheArchitecture) {
  HiddenModel model(SmallConfig(16), true, 9);
  // Non-default BN statistics must survive too.
  model.DecoderParameters()[4]->value[0] = 0.25f;
  SaveHiddenModel(Path("m.bin"), model, true);
  auto loaded = LoadHiddenModel(Path("m.bin"), true, 16);
  EXPECT_EQ(loaded->config.num_bits, 16);
  EXPECT_EQ(loaded->config.channels, 6);
  std::vector<Parameter*> a = model.AllParameters(),
                          b = loaded->AllParameters();
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k]->name, b[k]->name);
    EXPECT_EQ(a[k]->shape, b[k]->shape);
    EXPECT_EQ(a[k]->value, b[k]->value) << a[k]->name;
  }
}

TEST_F(NetworkFileTest, DecoderOnlyFileHasNoEncoder) {
  HiddenModel model(SmallConfig(8), true, 9);
  SaveHiddenModel(Path("d.bin"), model, false);
  EXPECT_EQ(LoadHiddenModel(Path("d.bin"), false)->encoder, nullptr);
  EXPECT_NE(LoadError(Path("d.bin"), true).find("no encoder"),
            std::string::npos);
}

TEST_F(NetworkFileTest, RefusesTruncatedCorruptedAndForeignFiles) {
  HiddenModel model(SmallConfig(8), true, 9);
  const std::string bytes =
      SerializeNetworkFile(HiddenModelToFile(model, true));
  const std::string path = Path("bad.bin");
  for (size_t keep :
       {size_t(0), size_t(5), size_t(40), bytes.size() / 2, bytes.size() - 1}) {
    WriteBytes(path, bytes.substr(0, keep));
    const std::string error = LoadError(path);
    EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << keep << ": " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos);
  }
  std::string flipped = bytes;
  flipped[bytes.size() / 3] ^= 0x10;
  WriteBytes(path, flipped);
  EXPECT_NE(LoadError(path).find("checksum"), std::string::npos);
  WriteBytes(path, "P6\n2 2\n255\n" + std::string(12, 'x') + "padding");
  EXPECT_NE(LoadError(path).find("not a watergs network file"),
            std::string::npos);
  EXPECT_NE(LoadError(Path("missing.bin")).find(Path("missing.bin")),
            std::string::npos);
}

TEST_F(NetworkFileTest, RefusesWrongArchitecture) {
  HiddenModel model(SmallConfig(8), true, 9);
  SaveHiddenModel(Path("m8.bin"), model, true);
  EXPECT_NE(LoadError(Path("m8.bin"), false, 48).find("wrong architecture"),
            std::string::npos);
  // A tensor of the wrong shape ([6,3,3,3] stored as [3,6,3,3]), with a
  // valid checksum.
  NetworkFile file = HiddenModelToFile(model, true);
  std::swap(file.tensors[0].shape[0], file.tensors[0].shape[1]);
  WriteNetworkFile(Path("shape.bin"), file);
  EXPECT_NE(LoadError(Path("shape.bin")).find("wrong architecture: tensor"),
            std::string::npos);
  // A missing tensor.
  file = HiddenModelToFile(model, true);
  file.tensors.pop_back();
  WriteNetworkFile(Path("missing_tensor.bin"), file);
  EXPECT_NE(LoadError(Path("missing_tensor.bin")).find("missing tensor"),
            std::string::npos);
  // Header claiming more decoder blocks than the tensors hold.
  file = HiddenModelToFile(model, true);
  for (auto& [key, value] : file.meta)
    if (key == "decoder_blocks") value = 5;
  WriteNetworkFile(Path("blocks.bin"), file);
  EXPECT_NE(LoadError(Path("blocks.bin")).find("wrong architecture"),
            std::string::npos);
  // An unknown version.
  std::string bytes = SerializeNetworkFile(HiddenModelToFile(model, true));
  bytes[8] = 7;
  WriteBytes(Path("v7.bin"), bytes);
  EXPECT_NE(
      LoadError(Path("v7.bin")).find("unsupported network file version 7"),
      std::string::npos);
}

}  // namespace
}  // namespace watergs
