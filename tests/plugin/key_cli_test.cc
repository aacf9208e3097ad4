// CLI tests of the owner's key (issue 27): a model embedded under a key
// reads "present" only for the message under that key, in extract, detect
// and report alike, whether the key is typed or read from a file; and
// `null_calibration` reads unmarked views from extract's JSON.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"
#include "plugin/workspace.h"
#include "tests/plugin/rendered_images.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/message.h"
#include "watermark/verification.h"

namespace watergs {
namespace {

using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kMessage = "text:owner";
const std::string kKey = "correct horse battery staple";
const std::string kDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

bool Present(const std::string& output) {
  return output.find("verdict: watermark present") != std::string::npos;
}

// The counts a Binomial(n, p) count stays within but with probability at
// most `tail` on each side: the largest `low` with P[X < low] <= tail and the
// smallest `high` with P[X > high] <= tail.
struct CountBounds {
  int low = 0, high = 0;
};
CountBounds BinomialBounds(int n, double p, double tail) {
  std::vector<double> pmf(size_t(n) + 1);
  pmf[0] = std::pow(1 - p, n);
  for (int k = 0; k < n; ++k)
    pmf[k + 1] = pmf[k] * (n - k) / (k + 1) * p / (1 - p);
  CountBounds b;
  double below = 0;  // P[X < k]
  for (int k = 0; k <= n && below <= tail; below += pmf[k++]) b.low = k;
  double above = 0;  // P[X > k]
  b.high = n;
  for (int k = n - 1; k >= 0 && above + pmf[k + 1] <= tail; --k) {
    above += pmf[k + 1];
    b.high = k;
  }
  return b;
}

// The line of `text` that starts with `prefix` ("" if none).
std::string LineStartingWith(const std::string& text,
                             const std::string& prefix) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) == 0) return line;
  }
  return "";
}

TEST(KeyCli, OnlyTheKeyedClaimReadsPresent) {
  TempDir dir("key_cli");
  testing::SyntheticModelOptions options;
  options.num_images = 6;
  options.width = 48;
  options.height = 36;
  GaussianModel raw;
  WorkspaceOptions wo;
  wo.workspace_path = testing::MakeRenderedWorkspace(dir / "ws", options, &raw);
  WritePly(dir / "raw.ply", raw);
  const std::string key_file = dir / "owner.key";
  {
    std::ofstream out(key_file);
    out << kKey << "\n";
  }
  const auto embed = RunCommand(
      WatergsBin() + " embed --input_path " + (dir / "raw.ply") +
      " --workspace_path " + wo.workspace_path + " --decoder " + kDecoder +
      " --message " + kMessage + " --key 'file:" + key_file +
      "' --output_path " + (dir / "wm.ply") +
      " --iterations 800 --distortions none --free_view_fraction 0"
      " --check_free_views 0 --reading blind --num_threads 2");
  ASSERT_EQ(embed.exit_code, 0) << embed.output;
  // The fingerprint an owner registers: SHA-256 of the key's bytes.
  EXPECT_NE(embed.output.find("key SHA-256 " + KeyFingerprint(kKey)),
            std::string::npos)
      << embed.output;

  const std::string extract = WatergsBin() + " extract --input_path " +
                              (dir / "wm.ply") + " --workspace_path " +
                              wo.workspace_path + " --decoder " + kDecoder +
                              " --message " + kMessage;
  const auto keyed = RunCommand(extract + " --key '" + kKey + "'");
  ASSERT_EQ(keyed.exit_code, 0) << keyed.output;
  EXPECT_TRUE(Present(keyed.output)) << keyed.output;
  // Under the key the bits read are the message the owner typed.
  EXPECT_NE(keyed.output.find("message under the key hex " +
                              BitsToHex(ParseMessage(kMessage, 48))),
            std::string::npos)
      << keyed.output;
  const auto from_file = RunCommand(extract + " --key file:" + key_file);
  EXPECT_TRUE(Present(from_file.output)) << from_file.output;
  const auto unkeyed = RunCommand(extract);
  ASSERT_EQ(unkeyed.exit_code, 0) << unkeyed.output;
  EXPECT_FALSE(Present(unkeyed.output)) << unkeyed.output;
  const auto wrong_key = RunCommand(extract + " --key 'correct horse'");
  EXPECT_FALSE(Present(wrong_key.output)) << wrong_key.output;
  const auto missing = RunCommand(extract + " --key file:" + (dir / "nokey"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find(dir / "nokey"), std::string::npos)
      << missing.output;

  // eval under the key: the identity row reads "present"; without the key
  // (the raw message claimed) it does not.
  auto eval_verdict = [&](const std::string& key_option,
                          const std::string& name) {
    const std::string prefix = dir / name;
    const auto run = RunCommand(
        WatergsBin() + " eval --raw_path " + (dir / "raw.ply") +
        " --input_path " + (dir / "wm.ply") + " --workspace_path " +
        wo.workspace_path + " --decoder " + kDecoder + " --message " +
        kMessage + key_option +
        " --attacks identity --image_attacks '' --lpips_weights '' --split "
        "all --output_path " +
        prefix);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    const nlohmann::json report =
        nlohmann::json::parse(std::ifstream(prefix + ".json"));
    for (const auto& row : report["robustness"]) {
      if (row["model"] == "watermarked" && row["attack"] == "identity") {
        return row["verdict"].get<std::string>();
      }
    }
    return std::string("no identity row");
  };
  EXPECT_EQ(eval_verdict(" --key '" + kKey + "'", "eval_keyed"),
            "watermark present");
  EXPECT_NE(eval_verdict("", "eval_unkeyed"), "watermark present");

  // detect on the renders as image files, with and without the key.
  const Workspace workspace = Workspace::Open(wo);
  const std::string pngs = dir / "png";
  CreateDirectories(pngs);
  const std::vector<ImageRGB> renders =
      testing::RenderViews(ReadPly(dir / "wm.ply").model, workspace);
  for (size_t k = 0; k < renders.size(); ++k) {
    WriteImageFile(pngs + "/view_" + std::to_string(k) + ".png", renders[k]);
  }
  const std::string detect = WatergsBin() + " detect --decoder " + kDecoder +
                             " --image_path " + pngs + " --message " + kMessage;
  EXPECT_TRUE(Present(RunCommand(detect + " --key '" + kKey + "'").output));
  EXPECT_FALSE(Present(RunCommand(detect).output));

  // The report names the key by its fingerprint and repeats --key.
  const std::string html = dir / "report.html";
  const auto report =
      RunCommand(WatergsBin() + " report --raw_path " + (dir / "raw.ply") +
                 " --input_path " + (dir / "wm.ply") + " --workspace_path " +
                 wo.workspace_path + " --decoder " + kDecoder + " --message " +
                 kMessage + " --key file:" + key_file + " --output_path " +
                 html + " --image_attacks '' --show_views 1");
  ASSERT_EQ(report.exit_code, 0) << report.output;
  std::ifstream in(html);
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  EXPECT_NE(text.find(KeyFingerprint(kKey)), std::string::npos);
  EXPECT_NE(text.find("--key file:" + key_file), std::string::npos);
  EXPECT_NE(text.find("watermark present"), std::string::npos);

  // The raw model's views, as extract writes them, are a null group.
  const std::string raw_json = dir / "raw_views.json";
  const auto raw_extract =
      RunCommand(WatergsBin() + " extract --input_path " + (dir / "raw.ply") +
                 " --workspace_path " + wo.workspace_path + " --decoder " +
                 kDecoder + " --num_views 40 --json " + raw_json);
  ASSERT_EQ(raw_extract.exit_code, 0) << raw_extract.output;
  const auto null =
      RunCommand(WatergsBin() + " null_calibration --decoder " + kDecoder +
                 " --logits " + raw_json +
                 " --keys 50 --single_keys 1 --aggregate 1,6"
                 " --aggregates 30 --markdown " +
                 (dir / "null.md") + " --json " + (dir / "null.json"));
  ASSERT_EQ(null.exit_code, 0) << null.output;
  EXPECT_NE(null.output.find("raw_views 40"), std::string::npos) << null.output;
  EXPECT_NE(null.output.find("| text:WGS-26, 50 keys | 6 | 0.01 | "),
            std::string::npos)
      << null.output;

  // Its single-view rates on these real unmarked renders, recounted here
  // from extract's logits: a view passes a claim at 1e-2 with at most 15 of
  // 48 bits wrong; the keyed family is the message under keys
  // "null-calibration-0" to "-49".
  std::ifstream raw_in(raw_json);
  const nlohmann::json views = nlohmann::json::parse(raw_in)["views"];
  ASSERT_EQ(views.size(), 40u);
  const Bits message = ParseMessage("text:WGS-26", 48);
  int fixed_passes = 0, keyed_passes = 0;
  for (const auto& view : views) {
    const std::vector<float> logits = view["logits"];
    Bits bits(48);
    for (int i = 0; i < 48; ++i) bits[i] = logits[i] > 0;
    fixed_passes += HammingDistance(bits, message) <= 15;
    for (int k = 0; k < 50; ++k) {
      const Bits keyed =
          ApplyKey(message, "null-calibration-" + std::to_string(k));
      keyed_passes += HammingDistance(bits, keyed) <= 15;
    }
  }
  std::ifstream null_in(dir / "null.json");
  const nlohmann::json table = nlohmann::json::parse(null_in);
  int rows = 0;
  for (const auto& row : table["rows"]) {
    if (row["aggregate_size"] != 1 || row["nominal"] != 0.01) continue;
    const std::string claim = row["claim"];
    if (claim == "text:WGS-26, unkeyed") {
      EXPECT_EQ(row["trials"], 40);
      EXPECT_EQ(row["passes"], fixed_passes);
      ++rows;
    } else if (claim == "text:WGS-26, 50 keys") {
      EXPECT_EQ(row["trials"], 40 * 50);
      EXPECT_EQ(row["passes"], keyed_passes);
      ++rows;
    }
  }
  EXPECT_EQ(rows, 2);
  // Bounds on the counts themselves. Unmarked, a view's 48 bits match a
  // claim each with probability 1/2, so one (view, claim) trial passes with
  // p = P[Binomial(48, 1/2) >= 33 right] = 0.66%; n independent trials pass
  // Binomial(n, p) times, outside the bounds below with probability at most
  // 1e-5 on each side: at most 4 of the 40 unkeyed views (expected 0.27),
  // 1 to 31 of the 2,000 keyed trials (expected 13.3; each key's bits are an
  // independent SHA-256 stream, so every trial is Bernoulli(p) whatever the
  // views read). Far above: extract reads the claimed message from unmarked
  // renders, or null_calibration counts the wrong bits; none keyed: the keys
  // were not applied (the family is then the unkeyed claim 50 times).
  const double p = BinomialTailPValue(48 - 15, 48);
  const CountBounds unkeyed_bounds = BinomialBounds(40, p, 1e-5);
  const CountBounds keyed_bounds = BinomialBounds(40 * 50, p, 1e-5);
  EXPECT_EQ(unkeyed_bounds.high, 4);
  EXPECT_EQ(keyed_bounds.low, 1);
  EXPECT_EQ(keyed_bounds.high, 31);
  EXPECT_LE(fixed_passes, unkeyed_bounds.high) << "unkeyed passes of 40";
  EXPECT_GE(keyed_passes, keyed_bounds.low) << "keyed passes of 2,000";
  EXPECT_LE(keyed_passes, keyed_bounds.high) << "keyed passes of 2,000";
  // null.md is the table printed, the recounted passes in its rows.
  std::ifstream md_in(dir / "null.md");
  const std::string md((std::istreambuf_iterator<char>(md_in)),
                       std::istreambuf_iterator<char>());
  EXPECT_NE(null.output.find(md), std::string::npos) << md;
  EXPECT_NE(LineStartingWith(md, "| text:WGS-26, unkeyed | 1 | 0.01 | 15 | ")
                .find(" | 40 | " + std::to_string(fixed_passes) + " | "),
            std::string::npos)
      << md;
  EXPECT_NE(LineStartingWith(md, "| text:WGS-26, 50 keys | 1 | 0.01 | 15 | ")
                .find(" | 2000 | " + std::to_string(keyed_passes) + " | "),
            std::string::npos)
      << md;
}

TEST(KeyCli, NullCalibrationRefusesBadLogitFilesInOneLine) {
  TempDir dir("null_cli");
  const std::string base =
      WatergsBin() + " null_calibration --decoder " + kDecoder + " --logits ";
  const std::string not_json = dir / "a.json";
  AtomicWriteFile(not_json, "{ not json");
  const std::string no_views = dir / "b.json";
  AtomicWriteFile(no_views, "{\"mean_logits\": [1, 2]}");
  const std::string short_view = dir / "c.json";
  AtomicWriteFile(short_view, "{\"views\": [{\"logits\": [0.5, -1]}]}");
  for (const std::string& path : {not_json, no_views, short_view}) {
    const auto r = RunCommand(base + path);
    EXPECT_NE(r.exit_code, 0) << path;
    testing::ExpectOneLineError(r, path);
  }
  const auto none =
      RunCommand(WatergsBin() + " null_calibration --decoder " + kDecoder);
  EXPECT_NE(none.exit_code, 0);
  EXPECT_NE(none.output.find("--logits"), std::string::npos) << none.output;
}

}  // namespace
}  // namespace watergs
