// CLI tests of `watergs eval` and of the new attacks in `watergs attack` /
// `watergs extract` on a small synthetic workspace with a tiny random
// decoder: report contents (JSON and Markdown), the LPIPS note, held-out view
// selection, invariance of the decoded bits under shuffling and under a
// similarity transform with moved cameras, and one-line errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
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
using testing::WriteTinyDecoder;

// WS with 9 views (48x36; held out: views 0 and 8) rendered from Gaussians at
// the SfM points (written to raw.ply), a perturbed copy (wm.ply) and a tiny
// random 16-bit decoder (decoder.bin).
struct Scene {
  std::string ws, raw, wm, decoder;
};

Scene MakeScene(const TempDir& dir) {
  testing::SyntheticModelOptions options;
  options.num_images = 9;
  options.num_points = 150;
  options.width = 48;
  options.height = 36;
  const Reconstruction model = testing::MakeSyntheticReconstruction(options);
  Scene scene{dir / "ws", dir / "raw.ply", dir / "wm.ply", dir / "dec.bin"};
  WriteReconstruction(model, scene.ws + "/sparse/0", ModelFormat::kText);
  CreateDirectories(scene.ws + "/images");
  for (const auto& [id, image] : model.Images()) {
    WritePng(scene.ws + "/images/" + image.name, ImageRGB(48, 36));
  }
  WorkspaceOptions wo;
  wo.workspace_path = scene.ws;
  const Workspace workspace = Workspace::Open(wo);
  std::vector<float> xyz, rgb;
  workspace.PointCloud(&xyz, &rgb);
  GaussianModel truth = InitGaussiansFromPoints(xyz, rgb, 1);
  for (float& logit : truth.opacity_logits) logit = 2.f;
  for (size_t k = 0; k < truth.sh_rest.size(); ++k) {
    truth.sh_rest[k] = 0.05f * float(int(k % 7) - 3);
  }
  auto rasterizer = MakeCpuRasterizer();
  for (size_t v = 0; v < workspace.NumViews(); ++v) {
    ImageRGB image;
    rasterizer->Forward(truth, workspace.ViewCamera(v), RenderOptions{}, &image,
                        nullptr);
    WritePng(scene.ws + "/images/" + workspace.ViewName(v), image);
  }
  WritePly(scene.raw, truth);
  GaussianModel wm = truth;
  for (size_t k = 0; k < wm.sh_dc.size(); ++k) wm.sh_dc[k] += 0.02f;
  WritePly(scene.wm, wm);
  WriteTinyDecoder(scene.decoder);
  return scene;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST(EvalCli, WritesQualityAndRobustnessReports) {
  TempDir dir("eval_cli");
  const Scene s = MakeScene(dir);
  const std::string report = dir / "report";
  const std::string base = WatergsBin() + " eval --raw_path " + s.raw +
                           " --workspace_path " + s.ws + " --decoder " +
                           s.decoder + " --message hex:a5c3 --num_threads 2";
  // From a folder without data/lpips: the default weights are missing and
  // LPIPS is skipped with a note.
  const auto run =
      RunCommand("cd " + dir.path() + " && " + base + " --input_path " + s.wm +
                 " --output_path " + report);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("| watermarked vs ground truth |"),
            std::string::npos);
  const auto j = ReadJson(report + ".json");
  std::ifstream md(report + ".md");
  EXPECT_TRUE(md.good());
  // Held-out views: every 8th of 9 sorted views.
  ASSERT_EQ(j["views"].size(), 2u);
  EXPECT_EQ(j["views"][0], "frame_1000.png");
  EXPECT_EQ(j["views"][1], "frame_1008.png");
  ASSERT_EQ(j["quality"].size(), 3u);
  const auto& vs_gt = j["quality"][0];
  const auto& vs_raw = j["quality"][1];
  const auto& raw_gt = j["quality"][2];
  EXPECT_EQ(vs_gt["per_view"].size(), 2u);
  // The ground truth is the raw model's render (PNG-rounded): the raw model
  // is far closer to it than the perturbed one is.
  EXPECT_GT(raw_gt["mean"]["psnr"].get<double>(), 45.0);
  EXPECT_LT(vs_gt["mean"]["psnr"].get<double>(),
            raw_gt["mean"]["psnr"].get<double>() - 5);
  EXPECT_LT(vs_raw["mean"]["ms_ssim"].get<double>(), 1.0);
  EXPECT_EQ(vs_raw["mean"]["ms_ssim_scales"], 2);  // 36 px: 2 scales
  EXPECT_TRUE(vs_raw["mean"]["lpips"].is_null());
  EXPECT_NE(
      j["lpips_note"].get<std::string>().find("no weights at the default"),
      std::string::npos);
  // 10 model attacks, 4 image attacks, the raw model's row.
  const auto& rows = j["robustness"];
  ASSERT_EQ(rows.size(), 15u);
  std::map<std::string, nlohmann::json> by_attack;
  for (const auto& row : rows) {
    if (row["model"] == "watermarked") by_attack[row["attack"]] = row;
  }
  EXPECT_EQ(rows.back()["model"], "raw");
  EXPECT_EQ(
      by_attack.at("crop:0.1")["gaussians"].get<int>(),
      int(std::lround(0.9 * by_attack.at("identity")["gaussians"].get<int>())));
  // Shuffling renders identically; the similarity transform moves the
  // cameras with the scene: the same bits are read.
  const std::string identity_hex = by_attack.at("identity")["recovered_hex"];
  EXPECT_EQ(by_attack.at("shuffle")["recovered_hex"], identity_hex);
  for (const auto& [attack, row] : by_attack) {
    if (attack.rfind("similarity:", 0) == 0) {
      EXPECT_EQ(row["recovered_hex"], identity_hex);
    }
  }
  EXPECT_EQ(by_attack.count("jpeg:50"), 1u);
  // Each row's PSNR is that of what it decoded against the ground truth: the
  // identity and raw rows are the quality table's, and every row has one.
  EXPECT_NEAR(by_attack.at("identity")["psnr"].get<double>(),
              vs_gt["mean"]["psnr"].get<double>(), 1e-6);
  EXPECT_NEAR(rows.back()["psnr"].get<double>(),
              raw_gt["mean"]["psnr"].get<double>(), 1e-6);
  for (const auto& [attack, row] : by_attack) {
    ASSERT_TRUE(row["psnr"].is_number()) << attack;
  }
  // Shuffling renders the same scene; strong noise on the means ruins it.
  EXPECT_NEAR(by_attack.at("shuffle")["psnr"].get<double>(),
              by_attack.at("identity")["psnr"].get<double>(), 1e-3);
  const auto noisy = RunCommand(base + " --input_path " + s.wm +
                                " --attacks identity,gn:0.3 --image_attacks '' "
                                "--output_path " +
                                (dir / "noisy"));
  ASSERT_EQ(noisy.exit_code, 0) << noisy.output;
  const auto n = ReadJson(dir / "noisy.json")["robustness"];
  ASSERT_EQ(n.size(), 3u);
  EXPECT_EQ(n[1]["attack"], "gn:0.3");
  EXPECT_LT(n[1]["psnr"].get<double>(), n[0]["psnr"].get<double>() - 5);

  // The raw model against itself: infinite PSNR is written as null.
  const auto same = RunCommand(base + " --input_path " + s.raw +
                               " --attacks identity --image_attacks '' "
                               "--split all --output_path " +
                               (dir / "same"));
  ASSERT_EQ(same.exit_code, 0) << same.output;
  const auto k = ReadJson(dir / "same.json");
  EXPECT_EQ(k["views"].size(), 9u);
  EXPECT_TRUE(k["quality"][1]["mean"]["psnr"].is_null());
  EXPECT_DOUBLE_EQ(k["quality"][1]["mean"]["ms_ssim"].get<double>(), 1.0);
  EXPECT_EQ(k["robustness"].size(), 2u);

  // Bad input: one line naming the problem, no report written.
  const std::string bad = dir / "bad";
  ExpectOneLineError(RunCommand(base + " --input_path " + s.wm +
                                " --attacks sh0,blur:2 --output_path " + bad),
                     "blur:2");
  ExpectOneLineError(RunCommand(base + " --input_path " + s.wm +
                                " --image_attacks jpeg:0 --output_path " + bad),
                     "jpeg:0");
  ExpectOneLineError(RunCommand(base + " --input_path " + s.wm +
                                " --split some --output_path " + bad),
                     "--split");
  EXPECT_FALSE(std::filesystem::exists(bad + ".json"));
}

// --attack_draws N: the random 3D attacks are drawn N times; the main rows
// stay the first draw (the paper's one-draw protocol), a "draws" entry and a
// Markdown table give each figure's mean and range over the draws.
TEST(EvalCli, DrawsRandomAttacksManyTimesKeepingTheFirstDrawAsTheRow) {
  TempDir dir("eval_draws");
  const Scene s = MakeScene(dir);
  const std::string base =
      WatergsBin() + " eval --raw_path " + s.raw + " --input_path " + s.wm +
      " --workspace_path " + s.ws + " --decoder " + s.decoder +
      " --message hex:a5c3 --num_threads 2 --lpips_weights '' "
      "--image_attacks '' --attacks identity,crop:0.3,sh0";
  const auto one = RunCommand(base + " --output_path " + (dir / "one"));
  ASSERT_EQ(one.exit_code, 0) << one.output;
  const auto many =
      RunCommand(base + " --attack_draws 6 --output_path " + (dir / "many"));
  ASSERT_EQ(many.exit_code, 0) << many.output;
  const auto rows_one = ReadJson(dir / "one.json")["robustness"];
  const auto j = ReadJson(dir / "many.json");
  EXPECT_EQ(j["attack_draws"], 6);
  const auto rows = j["robustness"];
  ASSERT_EQ(rows.size(), 4u);
  // Only the attack whose renders depend on the draw is drawn again.
  EXPECT_FALSE(rows[0].contains("draws"));
  EXPECT_FALSE(rows[2].contains("draws"));
  const auto& crop = rows[1];
  ASSERT_EQ(crop["attack"], "crop:0.3");
  ASSERT_TRUE(crop.contains("draws"));
  EXPECT_EQ(crop["draws"]["count"], 6);
  EXPECT_EQ(crop["recovered_hex"], rows_one[1]["recovered_hex"]);
  EXPECT_EQ(crop["owner"]["view_ber"]["mean"],
            rows_one[1]["owner"]["view_ber"]["mean"]);
  for (const char* reading : {"blind", "owner"}) {
    const auto& row = std::string(reading) == "owner" ? crop["owner"] : crop;
    const auto& draws = std::string(reading) == "owner" ? crop["draws"]["owner"]
                                                        : crop["draws"];
    const double first = row["view_ber"]["mean"].get<double>();
    const double low = draws["view_ber"]["min"].get<double>();
    const double high = draws["view_ber"]["max"].get<double>();
    const double mean = draws["view_ber"]["mean"].get<double>();
    EXPECT_LE(low, first) << reading;
    EXPECT_GE(high, first) << reading;
    EXPECT_LE(low, mean) << reading;
    EXPECT_GE(high, mean) << reading;
  }
  // A crop removes another run of the file each draw: the owner's reading
  // (the difference from the raw renders) changes between draws. (The tiny
  // decoder's blind reading is set by the scene and reads the same.)
  EXPECT_LT(crop["draws"]["owner"]["view_ber"]["min"].get<double>(),
            crop["draws"]["owner"]["view_ber"]["max"].get<double>());
  // Every draw's figures are kept, the first being the row's; the verdict
  // counts add up to the draws and count what per_draw says.
  for (const bool owner : {false, true}) {
    const auto& side = owner ? crop["draws"]["owner"] : crop["draws"];
    const auto& per_draw = side["per_draw"];
    ASSERT_EQ(per_draw.size(), 6u);
    const auto& row = owner ? crop["owner"] : crop;
    EXPECT_EQ(per_draw[0]["view_ber"], row["view_ber"]["mean"]);
    EXPECT_EQ(per_draw[0]["bit_errors"], row["bit_errors"]);
    EXPECT_EQ(per_draw[0]["verdict"], row["verdict"]);
    int counted = 0;
    for (const char* v : {"present", "inconclusive", "absent"}) {
      int listed = 0;
      for (const auto& d : per_draw) {
        const std::string verdict = d["verdict"];
        listed += verdict.size() >= std::strlen(v) &&
                  verdict.compare(verdict.size() - std::strlen(v),
                                  std::string::npos, v) == 0;
      }
      EXPECT_EQ(side["verdicts"][v].get<int>(), listed) << v;
      counted += side["verdicts"][v].get<int>();
    }
    EXPECT_EQ(counted, 6);
    // Each figure's mean, min and max are those of per_draw's values.
    for (const char* figure : {"view_ber", "bit_errors"}) {
      double sum = 0, low = 1e300, high = -1e300;
      for (const auto& d : per_draw) {
        const double value = d[figure].get<double>();
        sum += value;
        low = std::min(low, value);
        high = std::max(high, value);
      }
      const auto& spread = side[figure];
      EXPECT_NEAR(spread["mean"].get<double>(), sum / 6, 1e-12)
          << figure << (owner ? " owner" : " blind");
      EXPECT_EQ(spread["min"].get<double>(), low) << figure;
      EXPECT_EQ(spread["max"].get<double>(), high) << figure;
    }
  }
  // Draw d is the same draw however many are drawn: 3 draws are the first 3
  // of 6 (so a shorter run reads as a prefix of a longer one).
  const auto few =
      RunCommand(base + " --attack_draws 3 --output_path " + (dir / "few"));
  ASSERT_EQ(few.exit_code, 0) << few.output;
  const auto few_crop = ReadJson(dir / "few.json")["robustness"][1]["draws"];
  ASSERT_EQ(few_crop["owner"]["per_draw"].size(), 3u);
  for (size_t d = 0; d < 3; ++d) {
    EXPECT_EQ(few_crop["owner"]["per_draw"][d],
              crop["draws"]["owner"]["per_draw"][d])
        << d;
    EXPECT_EQ(few_crop["per_draw"][d], crop["draws"]["per_draw"][d]) << d;
  }
  EXPECT_NE(many.output.find("## Over 6 draws of each random attack"),
            std::string::npos)
      << many.output;
  EXPECT_NE(many.output.find("| crop:0.3 | "), std::string::npos);
  EXPECT_EQ(one.output.find("draws of each random attack"), std::string::npos);
  ExpectOneLineError(RunCommand(base + " --attack_draws 0"), "--attack_draws");
  ExpectOneLineError(RunCommand(base + " --attack_draws -3"), "--attack_draws");
  ExpectOneLineError(RunCommand(base + " --attack_draws 1001"),
                     "--attack_draws");
}

TEST(AttackCli, NewAttacksKeepTheLayoutAndExtractFollowsTheTransform) {
  TempDir dir("attack_cli");
  const Scene s = MakeScene(dir);
  const std::string moved = dir / "moved.ply";
  const auto attack =
      RunCommand(WatergsBin() + " attack --input_path " + s.wm +
                 " --attack similarity:25,0.5,0,-1,2,shuffle,sh0 "
                 "--output_path " +
                 moved);
  ASSERT_EQ(attack.exit_code, 0) << attack.output;
  const PlyData in = ReadPly(s.wm), out = ReadPly(moved);
  ASSERT_EQ(out.layout.properties.size(), in.layout.properties.size());
  EXPECT_EQ(out.model.sh_degree, in.model.sh_degree);
  EXPECT_EQ(out.model.size(), in.model.size());
  for (float v : out.model.sh_rest) EXPECT_EQ(v, 0.f);
  ASSERT_TRUE(std::filesystem::exists(moved + ".transform.txt"));

  // sh0 on the original for comparison: the moved model read through the
  // transform file gives the same bits as the unmoved one.
  const std::string flat = dir / "flat.ply";
  ASSERT_EQ(RunCommand(WatergsBin() + " attack --input_path " + s.wm +
                       " --attack sh0 --output_path " + flat)
                .exit_code,
            0);
  const std::string extract = WatergsBin() + " extract --workspace_path " +
                              s.ws + " --decoder " + s.decoder +
                              " --message hex:a5c3";
  const auto reference = RunCommand(extract + " --input_path " + flat +
                                    " --json " + (dir / "flat.json"));
  const auto followed =
      RunCommand(extract + " --input_path " + moved + " --scene_transform " +
                 moved + ".transform.txt --json " + (dir / "moved.json"));
  const auto lost = RunCommand(extract + " --input_path " + moved + " --json " +
                               (dir / "lost.json"));
  ASSERT_EQ(reference.exit_code, 0) << reference.output;
  ASSERT_EQ(followed.exit_code, 0) << followed.output;
  ASSERT_EQ(lost.exit_code, 0) << lost.output;
  const auto flat_json = ReadJson(dir / "flat.json");
  const auto moved_json = ReadJson(dir / "moved.json");
  EXPECT_EQ(moved_json["recovered_hex"], flat_json["recovered_hex"]);
  EXPECT_NE(ReadJson(dir / "lost.json")["mean_logits"],
            flat_json["mean_logits"]);

  // Image attacks in extract, pruning in attack, bad specs refused.
  const auto jpeg =
      RunCommand(extract + " --input_path " + s.wm + " --image_attack jpeg:30");
  EXPECT_EQ(jpeg.exit_code, 0) << jpeg.output;
  const std::string pruned = dir / "pruned.ply";
  ASSERT_EQ(RunCommand(WatergsBin() + " attack --input_path " + s.wm +
                       " --attack prune:0.95 --output_path " + pruned)
                .exit_code,
            0);
  EXPECT_EQ(ReadPly(pruned).model.size(), 0u);  // opacity sigmoid(2) = 0.88
  ExpectOneLineError(RunCommand(extract + " --input_path " + s.wm +
                                " --scene_transform similarity:1,2"),
                     "similarity");
  ExpectOneLineError(
      RunCommand(WatergsBin() + " attack --input_path " + s.wm +
                 " --attack quant:40 --output_path " + (dir / "q.ply")),
      "quant:40");
}

}  // namespace
}  // namespace watergs
