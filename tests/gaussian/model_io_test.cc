// Tests of the one model loader: formats told by content whatever the file
// is called, writers chosen by extension, refusals of what no reader takes,
// and no NaN/Inf reaching a parameter from any format.
#include "gaussian/formats/model_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/formats/sog_io.h"
#include "gaussian/formats/splat_io.h"
#include "gaussian/formats/spz_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "tests/common/refusal.h"

namespace watergs {
namespace {

std::string TempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_model_io_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

GaussianModel RandomModel(size_t n, int sh_degree, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel m;
  m.sh_degree = sh_degree;
  m.Resize(n);
  for (auto* v : {&m.means, &m.log_scales, &m.quats, &m.opacity_logits,
                  &m.sh_dc, &m.sh_rest}) {
    for (float& x : *v) x = u(rng);
  }
  return m;
}

std::string Refusal(const std::string& path) {
  return testing::Refusal(path, [&] { ReadModelFile(path); });
}

// Every format saved under a name that says another: the content decides.
TEST(ModelIo, DetectsFormatsByContentNotExtension) {
  const GaussianModel model = RandomModel(300, 1, 3);
  struct Case {
    std::string name;
    GaussianFormat format;
    int sh_degree;
  };
  const std::string ply = TempPath("is_ply.spz");
  WritePly(ply, model);
  const std::string spz = TempPath("is_spz.ply");
  AtomicWriteFile(spz, EncodeSpz(model));
  const std::string compressed = TempPath("is_compressed.splat");
  AtomicWriteFile(compressed, EncodeCompressedPly(model));
  const std::string splat = TempPath("is_splat.compressed.ply");
  AtomicWriteFile(splat, EncodeSplat(model));
  const std::string sog = TempPath("is_sog.ply");
  AtomicWriteFile(sog, EncodeSog(model));
  const Case cases[] = {{ply, GaussianFormat::kPly, 1},
                        {spz, GaussianFormat::kSpz, 1},
                        {compressed, GaussianFormat::kCompressedPly, 1},
                        {splat, GaussianFormat::kSplat, 0},
                        {sog, GaussianFormat::kSog, 1}};
  for (const Case& c : cases) {
    EXPECT_EQ(DetectGaussianFormat(c.name), c.format) << c.name;
    const ModelData data = ReadModelFile(c.name);
    EXPECT_EQ(data.format, c.format) << c.name;
    EXPECT_EQ(data.model.size(), model.size()) << c.name;
    EXPECT_EQ(data.model.sh_degree, c.sh_degree) << c.name;
    EXPECT_EQ(data.model.CountNonFinite(), 0u) << c.name;
    // Non-PLY models come with Inria's layout, ready to be written back.
    EXPECT_EQ(data.layout.ShDegree(), c.sh_degree) << c.name;
    EXPECT_EQ(data.layout.extra_values.size(), 3 * model.size()) << c.name;
  }
  EXPECT_EQ(ReadModelFile(spz).format_detail,
            "SPZ version 3 (12 fractional bits)");
  EXPECT_EQ(ReadModelFile(sog).format_detail,
            "PlayCanvas SOG (bundled, SH palette of 256, written by watergs)");
}

TEST(ModelIo, WritesTheFormatTheExtensionNames) {
  EXPECT_EQ(OutputFormatForPath("a/b.SPZ"), GaussianFormat::kSpz);
  EXPECT_EQ(OutputFormatForPath("b.splat"), GaussianFormat::kSplat);
  EXPECT_EQ(OutputFormatForPath("b.sog"), GaussianFormat::kSog);
  EXPECT_EQ(OutputFormatForPath("b.Compressed.PLY"),
            GaussianFormat::kCompressedPly);
  EXPECT_EQ(OutputFormatForPath("b.ply"), GaussianFormat::kPly);
  EXPECT_EQ(OutputFormatForPath("spz"), GaussianFormat::kPly);
  const GaussianModel model = RandomModel(20, 2, 4);
  const PlyLayout layout = InriaPlyLayout(2, model.size());
  for (const char* name :
       {"out.spz", "out.splat", "out.compressed.ply", "out.sog", "out.ply"}) {
    const std::string path = TempPath(name);
    WriteModelFile(path, model, layout);
    EXPECT_EQ(DetectGaussianFormat(path), OutputFormatForPath(path)) << name;
  }
  // A PLY keeps the layout it is given (here: an extra property).
  PlyLayout extra = layout;
  extra.properties.push_back({"confidence"});
  extra.ZeroExtras(model.size());
  WriteModelFile(TempPath("extra.ply"), model, extra);
  EXPECT_EQ(ReadModelFile(TempPath("extra.ply")).layout.NumExtras(), 4);
}

TEST(ModelIo, RefusesWhatNoReaderTakes) {
  EXPECT_NE(Refusal(TempPath("missing.ply")).find("file not found"),
            std::string::npos);
  const std::string empty = TempPath("empty.splat");
  AtomicWriteFile(empty, "");
  EXPECT_NE(Refusal(empty).find("not a 3DGS model"), std::string::npos);
  const std::string binary = TempPath("noise.bin");
  AtomicWriteFile(binary, std::string(27, '\xfe'));
  EXPECT_NE(Refusal(binary).find("27 bytes is not a multiple of the 32-byte"),
            std::string::npos);
  // Text of a .splat's size is not taken for one.
  const std::string text = TempPath("notes.txt");
  AtomicWriteFile(text,
                  "these notes are 64 bytes long, a multiple of 32, "
                  "and plain text\n");
  EXPECT_NE(Refusal(text).find("a text file, not a 3DGS model"),
            std::string::npos);
  const std::string zip = TempPath("scene.sog");
  AtomicWriteFile(zip, std::string("PK\x03\x04", 4) + std::string(60, 'x'));
  EXPECT_NE(Refusal(zip).find("not a readable ZIP archive"), std::string::npos);
  // JSON that is not a SOG meta.json is text like any other.
  const std::string json = TempPath("other.json");
  AtomicWriteFile(json, "{\"means\": 1}\n");
  EXPECT_NE(Refusal(json).find("a text file, not a 3DGS model"),
            std::string::npos);
  const std::string v5 = TempPath("v5.spz");
  AtomicWriteFile(v5, std::string("NGSP\x05\0\0\0", 8) + std::string(24, 'x'));
  EXPECT_NE(Refusal(v5).find("uncompressed NGSP stream of version 5"),
            std::string::npos);
  // A cut file of each format names the problem.
  const GaussianModel model = RandomModel(300, 1, 5);
  const std::string spz = EncodeSpz(model);
  const std::string cut_spz = TempPath("cut.spz");
  AtomicWriteFile(cut_spz, spz.substr(0, spz.size() / 2));
  EXPECT_NE(Refusal(cut_spz).find("truncated"), std::string::npos);
  const std::string compressed = EncodeCompressedPly(model);
  const std::string cut_compressed = TempPath("cut.compressed.ply");
  AtomicWriteFile(cut_compressed, compressed.substr(0, compressed.size() - 1));
  EXPECT_NE(Refusal(cut_compressed).find("truncated"), std::string::npos);
  const std::string sog = EncodeSog(model);
  const std::string cut_sog = TempPath("cut.sog");
  AtomicWriteFile(cut_sog, sog.substr(0, sog.size() - 30));
  EXPECT_NE(Refusal(cut_sog).find("not a readable ZIP archive"),
            std::string::npos);
  const std::string splat = EncodeSplat(model);
  const std::string cut_splat = TempPath("cut.splat");
  AtomicWriteFile(cut_splat, splat.substr(0, splat.size() - 5));
  EXPECT_NE(Refusal(cut_splat).find("not a multiple of the 32-byte"),
            std::string::npos);
}

// A .splat whose first float happens to start with the gzip signature is
// still read as .splat; a damaged SPZ is still refused as SPZ.
TEST(ModelIo, SplatStartingLikeGzipIsStillASplat) {
  GaussianModel model = RandomModel(4, 0, 6);
  std::string bytes = EncodeSplat(model);
  bytes[0] = char(0x1f);
  bytes[1] = char(0x8b);
  const std::string path = TempPath("gzip_like.splat");
  AtomicWriteFile(path, bytes);
  const ModelData data = ReadModelFile(path);
  EXPECT_EQ(data.format, GaussianFormat::kSplat);
  EXPECT_EQ(data.model.size(), 4u);
  std::string spz = EncodeSpz(model);
  spz.resize(64, 'x');  // a multiple of 32, but neither format:
  const float negative_scale = -1.f;
  std::memcpy(&spz[44], &negative_scale, 4);
  AtomicWriteFile(path, spz);
  const std::string message = Refusal(path);
  EXPECT_TRUE(message.find("SPZ") != std::string::npos ||
              message.find("gzip") != std::string::npos)
      << message;
}

TEST(ModelIo, WarnsOnceForZeroScalesOfASplat) {
  GaussianModel model = RandomModel(10, 0, 7);
  for (int i : {1, 4, 5}) model.log_scales[i] = -200.f;  // exp underflows
  const std::string path = TempPath("flat.splat");
  WriteSplat(path, model);
  std::ostringstream warnings;
  PlyReadOptions options;
  options.warnings = &warnings;
  const ModelData data = ReadModelFile(path, options);
  EXPECT_EQ(data.replaced_infinities, 3u);
  EXPECT_EQ(data.model.log_scales[4], kLogScaleFloor);
  EXPECT_EQ(warnings.str(),
            "warning: " + path +
                ": 3 infinite opacity logits or log-scales read as what "
                "viewers render (logit +-20 = alpha 0 or 1, log-scale -20 = "
                "flat)\n");
}

}  // namespace
}  // namespace watergs
