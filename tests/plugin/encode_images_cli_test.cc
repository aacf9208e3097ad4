// CLI test of `watergs encode_images` (the HiDDeN + 3DGS baseline's image
// step): every PNG/JPEG of a folder written watermarked under its own name,
// losslessly, equal to the in-process encoder's output up to 8-bit rounding,
// the report's figures; bad input refused in one line without
// writing anything.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "plugin/image_file.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/hidden_model.h"
#include "watermark/image_encoding.h"
#include "watermark/message.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;
using testing::RunCommand;
using testing::WatergsBin;

// A smooth random image.
ImageRGB Cover(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.2f, 0.8f);
  const float a = u(rng), b = u(rng);
  ImageRGB image(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        image.At(x, y)[c] = 0.5f + 0.3f * std::sin(a * x + b * y + c);
  return image;
}

struct Folder {
  fs::path root, covers, model;
  ~Folder() { fs::remove_all(root); }
};

// Two PNGs, one JPEG, a non-image file, and a tiny 8-bit HiDDeN model with
// (model) and without (decoder_only) its encoder.
void MakeFolder(Folder* f, HiddenModel* net) {
  f->root = fs::temp_directory_path() /
            ("watergs_encode_images_" + std::to_string(::getpid()));
  f->covers = f->root / "covers";
  fs::create_directories(f->covers);
  WriteImageFile((f->covers / "a.png").string(), Cover(24, 16, 1));
  WriteImageFile((f->covers / "b.png").string(), Cover(20, 20, 2));
  WriteImageFile((f->covers / "c.jpg").string(), Cover(16, 24, 3));
  std::ofstream((f->covers / "notes.txt").string()) << "not an image\n";
  f->model = f->root / "model.bin";
  SaveHiddenModel(f->model.string(), *net, true);
  SaveHiddenModel((f->root / "decoder_only.bin").string(), *net, false);
}

HiddenConfig TinyConfig() {
  HiddenConfig config;
  config.num_bits = 8;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 1;
  return config;
}

TEST(EncodeImagesCli, WritesEveryImageWatermarkedUnderItsName) {
  HiddenModel net(TinyConfig(), true, 4);
  Folder f;
  MakeFolder(&f, &net);
  const fs::path out = f.root / "out";
  const CommandResult run =
      RunCommand(WatergsBin() + " encode_images --image_path " +
                 f.covers.string() + " --output_path " + out.string() +
                 " --model " + f.model.string() + " --message bits:10110010");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("encoded 3 images"), std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("BER"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(out / "notes.txt"));
  const Bits message = ParseMessage("bits:10110010", 8);
  for (const char* name : {"a.png", "b.png", "c.jpg"}) {
    SCOPED_TRACE(name);
    const ImageRGB cover = ReadImageFile((f.covers / name).string());
    const ImageRGB written = ReadImageFile((out / name).string());
    ASSERT_EQ(written.width, cover.width);
    ASSERT_EQ(written.height, cover.height);
    const ImageRGB expected = EncodeImage(net, cover, message);
    const double tolerance = 0.5 / 255 + 1e-6;  // 8-bit rounding
    double worst = 0, moved = 0;
    for (size_t i = 0; i < expected.data.size(); ++i) {
      worst =
          std::max(worst, double(std::abs(written.data[i] - expected.data[i])));
      moved =
          std::max(moved, double(std::abs(expected.data[i] - cover.data[i])));
    }
    EXPECT_LE(worst, tolerance);
    EXPECT_GT(moved, 2.0 / 255) << "the encoder should change the image";
  }
}

TEST(EncodeImagesCli, RefusesBadInputInOneLineWithoutWriting) {
  HiddenModel net(TinyConfig(), true, 4);
  Folder f;
  MakeFolder(&f, &net);
  const std::string base = WatergsBin() + " encode_images --image_path " +
                           f.covers.string() + " --message bits:1011";
  struct Case {
    std::string args, expected;
  } cases[] = {
      {" --output_path " + (f.root / "o1").string() + " --model " +
           (f.root / "decoder_only.bin").string(),
       (f.root / "decoder_only.bin").string()},
      {" --output_path " + (f.root / "o2").string() + " --model " +
           (f.root / "missing.bin").string(),
       (f.root / "missing.bin").string()},
      {" --output_path " + f.covers.string() + " --model " + f.model.string(),
       "must differ"},
  };
  for (const Case& c : cases) {
    const CommandResult run = RunCommand(base + c.args);
    EXPECT_NE(run.exit_code, 0) << c.args;
    EXPECT_NE(run.output.find(c.expected), std::string::npos) << run.output;
    EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1)
        << run.output;
  }
  EXPECT_FALSE(fs::exists(f.root / "o1"));
  EXPECT_FALSE(fs::exists(f.root / "o2"));
  EXPECT_FALSE(fs::exists(f.covers / "a.png.tmp"));
}

}  // namespace
}  // namespace watergs
