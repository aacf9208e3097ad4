// CLI tests of `watergs embed` and `watergs extract` on a small synthetic
// COLMAP workspace with a tiny random decoder: output layout, verdict output,
// JSON, and one-line errors for bad input.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

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

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;
using testing::WriteAsciiPlyWithNormals;
using testing::WriteTinyDecoder;

// WS/sparse/0 (6 pinhole views, 48x36) and WS/images rendered from `truth`.
std::string MakeWorkspace(const TempDir& dir, GaussianModel* truth) {
  return testing::MakeRenderedWorkspace(dir / "ws",
                                        testing::SmallSceneOptions(), truth);
}

TEST(EmbedCli, KeepsTheLayoutReportsVerdictsAndRefusesBadInput) {
  TempDir dir("embed_cli");
  GaussianModel truth;
  const std::string ws = MakeWorkspace(dir, &truth);
  // Input in a non-default layout: ASCII with non-zero normals.
  const std::string raw = WriteAsciiPlyWithNormals(dir / "raw.ply", truth);
  const std::string decoder = WriteTinyDecoder(dir / "decoder.bin");

  const std::string wm = dir / "wm.ply";
  const std::string base = WatergsBin() + " embed --input_path " + raw +
                           " --workspace_path " + ws + " --decoder " + decoder;
  const auto run = RunCommand(base + " --message hex:a5c3 --output_path " + wm +
                              " --iterations 12 --crop_size 24 --densify off "
                              "--check_every 6 --check_views 2 --num_threads "
                              "2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("per iteration"), std::string::npos);
  // 12 iterations checked every 6: two checks, timed apart from the steps
  // ("embed: checks 0.1 s, 2 of 0.0 s each").
  const size_t checks = run.output.find("embed: checks ");
  ASSERT_NE(checks, std::string::npos) << run.output;
  const std::string checks_line =
      run.output.substr(checks, run.output.find('\n', checks) - checks);
  EXPECT_NE(checks_line.find(" s, 2 of "), std::string::npos) << checks_line;
  EXPECT_NE(run.output.find(" 6 views "), std::string::npos) << run.output;
  // --split train holds out every 8th view (here view 0) as train --split train
  // does.
  const auto held_out =
      RunCommand(base + " --message hex:a5c3 --output_path " +
                 std::string(dir / "wm_eval.ply") +
                 " --iterations 2 --crop_size 24 --densify off --check_every 2"
                 " --num_threads 1 --split train");
  ASSERT_EQ(held_out.exit_code, 0) << held_out.output;
  EXPECT_NE(held_out.output.find(" 5 views "), std::string::npos)
      << held_out.output;
  const PlyData in = ReadPly(raw);
  const PlyData out = ReadPly(wm);
  EXPECT_EQ(out.layout.format, PlyFormat::kAscii);
  ASSERT_EQ(out.layout.properties.size(), in.layout.properties.size());
  for (size_t k = 0; k < in.layout.properties.size(); ++k) {
    EXPECT_EQ(out.layout.properties[k].name, in.layout.properties[k].name);
    EXPECT_EQ(out.layout.properties[k].type, in.layout.properties[k].type);
  }
  EXPECT_EQ(out.layout.extra_values, in.layout.extra_values);
  EXPECT_EQ(out.model.sh_degree, 1);
  EXPECT_NE(out.model.sh_dc, in.model.sh_dc);

  // A partial mask runs without density control unless asked (which is
  // refused, below) and leaves the frozen groups as they were read.
  const std::string masked = dir / "wm_masked.ply";
  const auto partial =
      RunCommand(base + " --message hex:a5c3 --output_path " + masked +
                 " --iterations 4 --crop_size 24 --mask f_dc --check_every 2"
                 " --num_threads 1");
  ASSERT_EQ(partial.exit_code, 0) << partial.output;
  EXPECT_NE(partial.output.find("density control off"), std::string::npos)
      << partial.output;
  const PlyData m = ReadPly(masked);
  EXPECT_EQ(m.model.means, in.model.means);
  EXPECT_EQ(m.model.log_scales, in.model.log_scales);
  EXPECT_EQ(m.model.quats, in.model.quats);
  EXPECT_EQ(m.model.opacity_logits, in.model.opacity_logits);
  EXPECT_EQ(m.model.sh_rest, in.model.sh_rest);
  EXPECT_NE(m.model.sh_dc, in.model.sh_dc);

  // Layers chosen per scene: the closing line says what became of each
  // candidate.
  const auto chosen = RunCommand(
      base + " --message hex:a5c3 --output_path " +
      std::string(dir / "wm_auto.ply") +
      " --iterations 4 --check_every 2 --check_views 2 --num_threads 1 "
      "--distortions auto:dropout:0.2,crop:0.1");
  ASSERT_EQ(chosen.exit_code, 0) << chosen.output;
  EXPECT_NE(chosen.output.find("distortions auto:dropout:0.2,crop:0.1"),
            std::string::npos)
      << chosen.output;
  EXPECT_NE(chosen.output.find("embed: distortion layers dropout:0.2 "),
            std::string::npos)
      << chosen.output;
  EXPECT_NE(chosen.output.find("; crop:0.1 "), std::string::npos)
      << chosen.output;

  // --reading both (the default: blind weight 0.5 steered to 38 dB): the
  // owner's reading plus the blind term moves the model elsewhere than the
  // owner's alone (same seed); at weight 0 it is the owner's run exactly (the
  // default target has no term to steer). The blind term's options with
  // another reading are refused.
  const std::string reading_run =
      base +
      " --message hex:a5c3 --iterations 4 --check_every 2 "
      "--check_views 2 --num_threads 1 --output_path ";
  const auto owner_only = RunCommand(
      reading_run + std::string(dir / "wm_owner.ply") + " --reading owner");
  const auto by_default =
      RunCommand(reading_run + std::string(dir / "wm_default.ply"));
  const auto both = RunCommand(reading_run + std::string(dir / "wm_both.ply") +
                               " --reading both --blind_weight 0.5 "
                               "--target_psnr 38");
  const auto fixed =
      RunCommand(reading_run + std::string(dir / "wm_fixed.ply") +
                 " --blind_weight 0.5 --target_psnr 0");
  const auto both_zero =
      RunCommand(reading_run + std::string(dir / "wm_both0.ply") +
                 " --reading both --blind_weight 0");
  ASSERT_EQ(owner_only.exit_code, 0) << owner_only.output;
  ASSERT_EQ(by_default.exit_code, 0) << by_default.output;
  ASSERT_EQ(both.exit_code, 0) << both.output;
  ASSERT_EQ(both_zero.exit_code, 0) << both_zero.output;
  ASSERT_EQ(fixed.exit_code, 0) << fixed.output;
  EXPECT_NE(ReadPly(dir / "wm_both.ply").model.sh_dc,
            ReadPly(dir / "wm_owner.ply").model.sh_dc);
  EXPECT_NE(ReadPly(dir / "wm_fixed.ply").model.sh_dc,
            ReadPly(dir / "wm_owner.ply").model.sh_dc);
  EXPECT_NE(by_default.output.find("(--target_psnr 38"), std::string::npos)
      << by_default.output;
  EXPECT_EQ(fixed.output.find("--target_psnr"), std::string::npos)
      << fixed.output;
  EXPECT_EQ(ReadPly(dir / "wm_default.ply").model.sh_dc,
            ReadPly(dir / "wm_both.ply").model.sh_dc);
  EXPECT_EQ(ReadPly(dir / "wm_both0.ply").model.sh_dc,
            ReadPly(dir / "wm_owner.ply").model.sh_dc);
  ExpectOneLineError(RunCommand(reading_run + std::string(dir / "wm_bad.ply") +
                                " --reading owner --blind_weight 2"),
                     "--reading both");
  // --target_psnr, checks at iterations 2 and 4: far below the renders'
  // PSNR the weight doubles at each, and iterations 3-4 train with the
  // doubled one (the model moves elsewhere); at the highest target (100 dB,
  // where a view's PSNR is capped) it stays at the given weight, its floor:
  // the fixed-weight run exactly.
  const auto spend = RunCommand(reading_run + std::string(dir / "wm_t1.ply") +
                                " --target_psnr 1");
  const auto keep = RunCommand(reading_run + std::string(dir / "wm_t100.ply") +
                               " --target_psnr 100");
  ASSERT_EQ(spend.exit_code, 0) << spend.output;
  ASSERT_EQ(keep.exit_code, 0) << keep.output;
  EXPECT_NE(spend.output.find("embed: blind weight 0.5 -> 2 after the last "
                              "check (--target_psnr 1"),
            std::string::npos)
      << spend.output;
  EXPECT_NE(keep.output.find("embed: blind weight 0.5 -> 0.5 after the last"),
            std::string::npos)
      << keep.output;
  EXPECT_NE(ReadPly(dir / "wm_t1.ply").model.sh_dc,
            ReadPly(dir / "wm_fixed.ply").model.sh_dc);
  EXPECT_EQ(ReadPly(dir / "wm_t100.ply").model.sh_dc,
            ReadPly(dir / "wm_fixed.ply").model.sh_dc);
  ExpectOneLineError(RunCommand(reading_run + std::string(dir / "wm_bad.ply") +
                                " --target_psnr 38 --blind_weight 100"),
                     "<= 64");
  // The default target holds the weight to the same bound, and says how to
  // leave it; without a target any weight goes.
  ExpectOneLineError(RunCommand(reading_run + std::string(dir / "wm_bad.ply") +
                                " --blind_weight 100"),
                     "--target_psnr 0");
  ASSERT_EQ(RunCommand(reading_run + std::string(dir / "wm_w100.ply") +
                       " --blind_weight 100 --target_psnr 0")
                .exit_code,
            0);
  ExpectOneLineError(RunCommand(reading_run + std::string(dir / "wm_bad.ply") +
                                " --reading owner --target_psnr 38"),
                     "--reading both");
  ExpectOneLineError(RunCommand(reading_run + std::string(dir / "wm_bad.ply") +
                                " --target_psnr -3"),
                     "target_psnr");

  // Extraction: a verdict (any) is exit 0, with the JSON written.
  const std::string json = dir / "extract.json";
  const auto extract = RunCommand(
      WatergsBin() + " extract --input_path " + raw + " --workspace_path " +
      ws + " --decoder " + decoder + " --message hex:a5c3 --json " + json);
  ASSERT_EQ(extract.exit_code, 0) << extract.output;
  EXPECT_NE(extract.output.find("verdict:"), std::string::npos);
  std::ifstream json_in(json);
  const auto j = nlohmann::json::parse(json_in);
  EXPECT_EQ(j["num_views"], 6);
  EXPECT_EQ(j["expected_bits"], "1010010111000011");
  EXPECT_NE(j["verdict"], "watermark present");

  // --crop_size auto, the default, keeps whole frames this small.
  const auto auto_crop = RunCommand(
      base + " --message hex:a5c3 --output_path " +
      std::string(dir / "wm_auto.ply") +
      " --iterations 1 --densify off --check_views 1 --num_threads 2");
  ASSERT_EQ(auto_crop.exit_code, 0) << auto_crop.output;
  EXPECT_NE(
      auto_crop.output.find(", whole frames (auto: frames up to 512x512),"),
      std::string::npos)
      << auto_crop.output;

  // Bad input: one line naming the problem, no output written.
  const std::string bad_out = dir / "bad.ply";
  ExpectOneLineError(
      RunCommand(WatergsBin() + " embed --input_path " + raw +
                 " --workspace_path " + ws + " --decoder " + raw +
                 " --message hex:a5 --output_path " + bad_out),
      raw);
  ExpectOneLineError(
      RunCommand(base + " --message hex:a5c3f --output_path " + bad_out),
      "decoder reads");
  ExpectOneLineError(
      RunCommand(base + " --message bits:01 --mask xyz,colour --output_path " +
                 bad_out),
      "colour");
  ExpectOneLineError(RunCommand(base +
                                " --message hex:a5c3 --mask f_dc --densify on "
                                "--output_path " +
                                bad_out),
                     "--densify on needs --mask ALL");
  ExpectOneLineError(
      RunCommand(base + " --message hex:a5c3 --densify maybe --output_path " +
                 bad_out),
      "--densify: on, off or auto");
  ExpectOneLineError(
      RunCommand(base + " --message hex:a5c3 --crop_size -8 --output_path " +
                 bad_out),
      "--crop_size: '-8' is not auto or a side in pixels");
  ExpectOneLineError(
      RunCommand(base + " --message hex:a5c3 --hard_views -2 --output_path " +
                 bad_out),
      "--hard_views must be >= 0");
  ExpectOneLineError(
      RunCommand(base +
                 " --message hex:a5c3 --hard_views 4 --free_view_fraction 0 "
                 "--output_path " +
                 bad_out),
      "--hard_views replays free-view iterations");
  ExpectOneLineError(
      RunCommand(base +
                 " --message hex:a5c3 --distortions auto --check_views 0 "
                 "--output_path " +
                 bad_out),
      "--distortions auto reviews the layers on the check views");
  ExpectOneLineError(RunCommand(base +
                                " --message hex:a5c3 --distortions auto:blur:2 "
                                "--output_path " +
                                bad_out),
                     "blur");
  ExpectOneLineError(RunCommand(WatergsBin() + " extract --input_path " + wm +
                                " --workspace_path " + ws + " --decoder " +
                                decoder + " --message bits:00110011001100110"),
                     "decoder reads");
  EXPECT_FALSE(std::filesystem::exists(bad_out));
}

}  // namespace
}  // namespace watergs
