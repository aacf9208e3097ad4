// CLI test of `watergs concat_embed` (the CONCAT + 3DGS baseline) on a small
// synthetic workspace with a tiny random decoder: the output keeps the
// input's PLY layout and every attribute but the chosen SH group, and bad
// input gives one-line errors naming what is wrong.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "gaussian/formats/ply_io.h"
#include "synthetic_model.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/hidden_model.h"
#include "watermark/message.h"

namespace watergs {
namespace {

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;
using testing::WriteAsciiPlyWithNormals;
using testing::WriteTinyDecoder;

TEST(ConcatEmbedCli, KeepsTheLayoutAndFrozenAttributesAndRefusesBadInput) {
  TempDir dir("concat_embed_cli");
  GaussianModel truth;
  const std::string ws = testing::MakeRenderedWorkspace(
      dir / "ws", testing::SmallSceneOptions(), &truth);
  // Input in a non-default layout: ASCII with non-zero normals.
  const std::string raw = WriteAsciiPlyWithNormals(dir / "raw.ply", truth);
  const std::string decoder = WriteTinyDecoder(dir / "decoder.bin");

  const std::string wm = dir / "wm.ply";
  const std::string base = WatergsBin() + " concat_embed --input_path " + raw +
                           " --workspace_path " + ws + " --decoder " + decoder +
                           " --message hex:a5c3 --num_threads 2";
  const auto run = RunCommand(base + " --output_path " + wm +
                              " --iterations 8 --crop_size 24 --hidden 8 "
                              "--attributes f_dc --check_views 2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("check views (2): BER"), std::string::npos)
      << run.output;
  const PlyData in = ReadPly(raw), out = ReadPly(wm);
  EXPECT_EQ(out.layout.format, PlyFormat::kAscii);
  EXPECT_EQ(out.layout.extra_values, in.layout.extra_values);
  EXPECT_NE(out.model.sh_dc, in.model.sh_dc);
  EXPECT_EQ(out.model.sh_rest, in.model.sh_rest);
  EXPECT_EQ(out.model.means, in.model.means);
  EXPECT_EQ(out.model.log_scales, in.model.log_scales);
  EXPECT_EQ(out.model.quats, in.model.quats);
  EXPECT_EQ(out.model.opacity_logits, in.model.opacity_logits);

  // --key: the bits written are the message XOR the key's stream (the line
  // names them), and the run is keyed; without it, the message itself.
  EXPECT_NE(run.output.find("16-bit message a5c3"), std::string::npos)
      << run.output;
  const std::string key = "concat test key";
  const auto keyed =
      RunCommand(base + " --output_path " + std::string(dir / "keyed.ply") +
                 " --iterations 2 --crop_size 24 --hidden 8 "
                 "--attributes f_dc --check_views 2 --key '" +
                 key + "'");
  ASSERT_EQ(keyed.exit_code, 0) << keyed.output;
  const std::string keyed_hex =
      BitsToHex(ApplyKey(ParseMessage("hex:a5c3", 16), key));
  ASSERT_NE(keyed_hex, "a5c3");
  EXPECT_NE(keyed.output.find("16-bit message " + keyed_hex), std::string::npos)
      << keyed.output;
  EXPECT_NE(keyed.output.find("keyed message"), std::string::npos)
      << keyed.output;

  const std::string bad_out = dir / "bad.ply";
  ExpectOneLineError(
      RunCommand(base + " --output_path " + bad_out + " --attributes xyz"),
      "--attributes");
  const std::string missing = dir / "missing.bin";
  ExpectOneLineError(
      RunCommand(WatergsBin() + " concat_embed --input_path " + raw +
                 " --workspace_path " + ws + " --decoder " + missing +
                 " --message hex:a5c3 --output_path " + bad_out),
      missing);
  ExpectOneLineError(RunCommand(base + " --output_path " + raw), "differ");
  // The same file spelled differently is refused too.
  const std::string raw_respelled = dir / "./raw.ply";
  ExpectOneLineError(RunCommand(base + " --output_path " + raw_respelled),
                     "differ");
  EXPECT_FALSE(std::filesystem::exists(bad_out));
}

}  // namespace
}  // namespace watergs
