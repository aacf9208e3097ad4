// CLI tests of `watergs report` (and `eval --report`, `embed --report`) on a
// small rendered workspace with a tiny random decoder: the page is
// self-contained, its claim and every attack row are what the commands it
// lists print, user text is escaped, bad input fails in one line without
// touching the output; and the page, opened in headless Chromium, shows every
// image decoded where it stands, with no console message.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <regex>
#include <sstream>

#include "gaussian/formats/ply_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/ownership_report.h"
#include "plugin/report_evidence.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;
using testing::WriteTinyDecoder;

// WS with 9 views of 96x72 rendered from Gaussians at its SfM points (the
// raw model), a watermarked stand-in whose colours are shifted at random
// (visible in the difference image) and a tiny random 16-bit decoder.
struct Scene {
  std::string ws, raw, wm, decoder;
};

Scene MakeScene(const TempDir& dir, const std::string& wm_name) {
  testing::SyntheticModelOptions options;
  options.num_images = 9;
  options.num_points = 150;
  options.width = 96;
  options.height = 72;
  GaussianModel truth;
  Scene s{testing::MakeRenderedWorkspace(dir / "ws", options, &truth),
          dir / "raw.ply", dir / wm_name, dir / "decoder.bin"};
  WritePly(s.raw, truth);
  // A shift per Gaussian and channel: the difference image has structure.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> shift(-0.3f, 0.3f);
  for (float& dc : truth.sh_dc) dc += shift(rng);
  WritePly(s.wm, truth);
  WriteTinyDecoder(s.decoder);
  return s;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The page's JSON block.
nlohmann::json ReportData(const std::string& html) {
  const std::string open =
      "<script type=\"application/json\" id=\"watergs-report-data\">";
  const size_t begin = html.find(open);
  const size_t end = html.find("</script>", begin);
  if (begin == std::string::npos || end == std::string::npos) return nullptr;
  return nlohmann::json::parse(
      html.substr(begin + open.size(), end - begin - open.size()));
}

// A command from the page run with the binary under test, from `dir`.
testing::CommandResult RunListed(const std::string& command,
                                 const std::string& dir) {
  std::string line = command;
  for (size_t at = 0; (at = line.find("watergs ", at)) != std::string::npos;) {
    if (at == 0 || (at >= 3 && line.compare(at - 3, 3, "&& ") == 0)) {
      line.replace(at, 7, WatergsBin());
      at += WatergsBin().size();
    } else {
      at += 8;
    }
  }
  return RunCommand("cd " + dir + " && " + line);
}

TEST(ReportCli, ClaimAndEveryRowAreWhatTheListedCommandsPrint) {
  TempDir dir("report_cli");
  // A name that needs shell quoting in the listed commands.
  const Scene s = MakeScene(dir, "w'm 1.ply");
  const std::string q_wm = "\"" + s.wm + "\"";
  const std::string copy = dir / "copy.ply";
  ASSERT_EQ(RunCommand(WatergsBin() + " attack --input_path " + q_wm +
                       " --attack dropout:0.2 --output_path " + copy)
                .exit_code,
            0);
  // The claim: what the decoder reads from the watermarked stand-in (all 16
  // bits right, p = 2^-16), present at a false-positive rate of 1e-4. This
  // checks the page's mechanics only: a claim read off the suspect first has
  // no false-positive rate at all (docs/verification.md), which is what the
  // page's "Owner's key" row tells a reader of an unkeyed claim.
  const std::string common = " --workspace_path " + s.ws + " --decoder " +
                             s.decoder + " --max_views 6 --num_threads 2";
  const auto read = RunCommand(WatergsBin() + " extract --input_path " + q_wm +
                               common + " --json " + (dir / "read.json"));
  ASSERT_EQ(read.exit_code, 0) << read.output;
  const std::string hex =
      nlohmann::json::parse(ReadText(dir / "read.json"))["recovered_hex"];
  const std::string page = dir / "report.html";
  const auto run = RunCommand(
      WatergsBin() + " report --raw_path " + s.raw + " --input_path " + q_wm +
      common + " --message hex:" + hex +
      " --reading blind --false_positive_rate 1e-4 --attacks "
      "gn:0.02,dropout:0.3,"
      "similarity:30,0.1,-0.2,0.3,1.5 --image_attacks jpeg:50 --copies " +
      copy + " --show_views 2 --output_path " + page);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("verdict: watermark present"), std::string::npos)
      << run.output;
  const std::string html = ReadText(page);
  ASSERT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("<div class=\"verdict\">watermark present</div>"),
            std::string::npos);
  EXPECT_NE(html.find("claim fixed before the model was read"),
            std::string::npos);
  // Self-contained: 2 views x 3 images, all data URIs; nothing fetched, no
  // script but the JSON block.
  size_t images = 0;
  for (size_t at = 0; (at = html.find("<img ", at)) != std::string::npos;
       ++at) {
    ++images;
    const size_t src = html.find(" src=\"", at);
    EXPECT_EQ(html.compare(src + 6, 22, "data:image/png;base64,"), 0);
  }
  EXPECT_EQ(images, 6u);
  EXPECT_EQ(html.find("http"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find("<script"), html.rfind("<script"));

  const nlohmann::json data = ReportData(html);
  ASSERT_TRUE(data.is_object());
  EXPECT_EQ(data["claim"]["verdict"], "watermark present");
  EXPECT_EQ(data["claim"]["recovered_hex"], hex);
  // The decoder's checksum: FNV-1a 64 of the file.
  const std::vector<uint8_t> decoder_bytes = ReadFileBytes(s.decoder);
  char fnv[20];
  std::snprintf(fnv, sizeof(fnv), "%llx",
                static_cast<unsigned long long>(
                    Fnv1a64(decoder_bytes.data(), decoder_bytes.size())));
  EXPECT_EQ(data["files"][0]["role"], "decoder");
  EXPECT_EQ(data["files"][0]["fnv1a"], fnv);
  EXPECT_EQ(data["files"][0]["bytes"], decoder_bytes.size());

  // The listed commands reproduce the claim and each row: identity and
  // three model attacks (one moving the scene), one attack on the renders,
  // the raw model, the suspect copy.
  const nlohmann::json& rows = data["evaluation"]["robustness"];
  ASSERT_EQ(rows.size(), 7u);
  ASSERT_EQ(data["row_commands"].size(), rows.size());
  const std::string claim_command = data["commands"][1]["command"];
  // Every bar of the chart shows, a view read all right too.
  EXPECT_NE(html.find("<rect class=\"wm\""), std::string::npos);
  EXPECT_EQ(html.find("height=\"0.0\""), std::string::npos);
  // On the page the command's options do not wrap inside ("--" at a line's
  // end, "decoder" on the next), and its text is the command's.
  const size_t pre = html.find("<pre>", html.find("The claim alone"));
  ASSERT_NE(pre, std::string::npos);
  std::string shown = html.substr(pre + 5, html.find("</pre>", pre) - pre - 5);
  EXPECT_NE(shown.find("<span class=\"opt\">--decoder</span>"),
            std::string::npos)
      << shown;
  shown = std::regex_replace(shown, std::regex("<[^>]*>"), "");
  shown = std::regex_replace(shown, std::regex("&#39;"), "'");
  shown = std::regex_replace(shown, std::regex("&quot;"), "\"");
  shown = std::regex_replace(shown, std::regex("&lt;"), "<");
  shown = std::regex_replace(shown, std::regex("&gt;"), ">");
  shown = std::regex_replace(shown, std::regex("&amp;"), "&");
  EXPECT_EQ(shown, claim_command);
  const auto claim =
      RunListed(claim_command + " --json claim.json", dir.path());
  ASSERT_EQ(claim.exit_code, 0) << claim_command << "\n" << claim.output;
  const auto claim_json = nlohmann::json::parse(ReadText(dir / "claim.json"));
  EXPECT_EQ(claim_json["recovered_hex"], hex);
  EXPECT_DOUBLE_EQ(claim_json["p_value"].get<double>(),
                   data["claim"]["p_value"].get<double>());
  for (size_t k = 0; k < rows.size(); ++k) {
    const std::string command = data["row_commands"][k];
    const auto again = RunListed(command + " --json row.json", dir.path());
    ASSERT_EQ(again.exit_code, 0) << command << "\n" << again.output;
    const auto row = nlohmann::json::parse(ReadText(dir / "row.json"));
    EXPECT_EQ(row["recovered_hex"], rows[k]["recovered_hex"]) << command;
    EXPECT_EQ(row["bit_errors"], rows[k]["bit_errors"]) << command;
    // The decoder's outputs, not only the bits (a random decoder reads the
    // same bits from differently attacked copies).
    ASSERT_EQ(row["mean_logits"].size(), rows[k]["mean_logits"].size());
    for (size_t i = 0; i < row["mean_logits"].size(); ++i) {
      EXPECT_NEAR(row["mean_logits"][i].get<double>(),
                  rows[k]["mean_logits"][i].get<double>(), 1e-6)
          << command << " logit " << i;
    }
  }
  EXPECT_EQ(rows[4]["attack"], "jpeg:50");
  EXPECT_EQ(rows[5]["model"], "raw");
  EXPECT_EQ(rows[6]["model"], "file");
  EXPECT_EQ(rows[6]["attack"], copy);
}

TEST(ReportCli, EscapesUserTextAndRefusesBadInputLeavingTheOutput) {
  TempDir dir("report_escape");
  const Scene s = MakeScene(dir, "a<b>&.ply");
  const std::string page = dir / "report.html";
  const std::string base = WatergsBin() + " report --raw_path " + s.raw +
                           " --workspace_path " + s.ws + " --decoder " +
                           s.decoder +
                           " --attacks identity --image_attacks '' "
                           "--show_views 1 --num_threads 2";
  const auto run = RunCommand(base + " --input_path '" + s.wm +
                              "' --message 'text:<&' --output_path " + page);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const std::string html = ReadText(page);
  EXPECT_NE(html.find("<code>text:&lt;&amp;</code>"), std::string::npos);
  EXPECT_NE(html.find("a&lt;b&gt;&amp;.ply"), std::string::npos);
  EXPECT_EQ(html.find("text:<&"), std::string::npos);
  EXPECT_EQ(html.find("a<b>"), std::string::npos);
  EXPECT_EQ(ReportData(html)["message"], "text:<&");

  // Bad input: one line naming the problem, the existing page untouched.
  const std::string good = " --input_path '" + s.wm + "' --message hex:a5c3";
  const std::string missing = dir / "missing.ply";
  ExpectOneLineError(RunCommand(base + good + " --copies " + missing +
                                " --output_path " + page),
                     missing);
  ExpectOneLineError(RunCommand(base + " --input_path '" + s.wm +
                                "' --message hex:a5c3a5 --output_path " + page),
                     "bits");
  ExpectOneLineError(RunCommand(base + good + " --output_path " + s.raw),
                     "is one of the inputs");
  ExpectOneLineError(RunCommand(base + good + " --output_path " +
                                (dir / "no_such_folder/r.html")),
                     "no_such_folder");
  EXPECT_EQ(ReadText(page), html);
}

TEST(ReportCli, EvalAndEmbedWriteTheReportToo) {
  TempDir dir("report_eval_embed");
  const Scene s = MakeScene(dir, "wm.ply");
  const auto eval = RunCommand(
      WatergsBin() + " eval --raw_path " + s.raw + " --input_path " + s.wm +
      " --workspace_path " + s.ws + " --decoder " + s.decoder +
      " --message hex:a5c3 --attacks identity --image_attacks '' "
      "--lpips_weights '' --num_threads 2 --report " +
      (dir / "eval.html"));
  ASSERT_EQ(eval.exit_code, 0) << eval.output;
  const std::string eval_html = ReadText(dir / "eval.html");
  const nlohmann::json eval_data = ReportData(eval_html);
  ASSERT_TRUE(eval_data.is_object());
  // eval's 2 held-out views of 9 (0 and 8) are no spread extract makes:
  // the page says so instead of listing extract commands.
  EXPECT_EQ(eval_data["evaluation"]["views"].size(), 2u);
  EXPECT_TRUE(eval_data["row_commands"].empty());
  EXPECT_NE(eval_html.find("not a selection watergs extract makes"),
            std::string::npos);
  EXPECT_NE(eval_data["commands"][0]["command"].get<std::string>().find(
                "watergs eval --raw_path"),
            std::string::npos);

  // A report path in a missing folder fails before the evaluation.
  ExpectOneLineError(
      RunCommand(WatergsBin() + " eval --raw_path " + s.raw + " --input_path " +
                 s.wm + " --workspace_path " + s.ws + " --decoder " +
                 s.decoder + " --message hex:a5c3 --report " +
                 (dir / "missing/eval.html")),
      "missing");

  const std::string wm = dir / "embedded.ply";
  const std::string embed_page = dir / "embed.html";
  const auto embed = RunCommand(
      WatergsBin() + " embed --input_path " + s.raw + " --workspace_path " +
      s.ws + " --decoder " + s.decoder + " --message hex:a5c3 --output_path " +
      wm + " --iterations 2 --crop_size 24 --densify off --check_every 2 " +
      "--check_views 1 --num_threads 2 --report " + embed_page);
  ASSERT_EQ(embed.exit_code, 0) << embed.output;
  const nlohmann::json embed_data = ReportData(ReadText(embed_page));
  ASSERT_TRUE(embed_data.is_object());
  EXPECT_EQ(embed_data["evaluation"]["views"].size(), 9u);
  // The page's `watergs report` command writes the same figures from the
  // files.
  const std::string again = embed_data["commands"][1]["command"];
  ASSERT_NE(again.find("watergs report"), std::string::npos);
  const auto regenerated = RunListed(again, dir.path());
  ASSERT_EQ(regenerated.exit_code, 0) << again << "\n" << regenerated.output;
  const nlohmann::json regenerated_data = ReportData(ReadText(embed_page));
  EXPECT_EQ(regenerated_data["claim"], embed_data["claim"]);
  EXPECT_EQ(regenerated_data["evaluation"]["robustness"],
            embed_data["evaluation"]["robustness"]);
}

// ---- The page in a browser ----

std::string Base64Decode(const std::string& text) {
  std::string out;
  uint32_t word = 0;
  int bits = 0;
  for (const char c : text) {
    int v = -1;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    if (c >= '0' && c <= '9') v = c - '0' + 52;
    if (c == '+') v = 62;
    if (c == '/') v = 63;
    if (v < 0) continue;
    word = (word << 6) | uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += char((word >> bits) & 255);
    }
  }
  return out;
}

// The image data of <img id="`id`"> in the page, decoded (empty if none).
cv::Mat EmbeddedImage(const std::string& html, const std::string& id) {
  const size_t at = html.find("<img id=\"" + id + "\"");
  if (at == std::string::npos) return {};
  const std::string prefix = "src=\"data:image/png;base64,";
  const size_t src = html.find(prefix, at);
  const size_t end = html.find('"', src + prefix.size());
  const std::string png =
      Base64Decode(html.substr(src + prefix.size(), end - src - prefix.size()));
  return cv::imdecode(std::vector<uchar>(png.begin(), png.end()),
                      cv::IMREAD_COLOR);
}

struct PageCheck {
  // Chromium is missing: the check could not run.
  bool skipped = false;
  std::string screenshot;
  // Each problem in a line: console messages, images not decoded, blank,
  // outside the screenshot or unlike their data.
  std::vector<std::string> problems;
  size_t images = 0;
  // Largest mean difference (0-255) between an image on screen and its data.
  double worst_difference = 0;
};

// Opens `page` in headless Chromium (scripts/screenshot_report.sh) and
// checks the screenshot where each image stands against the image's data.
PageCheck CheckInBrowser(const std::string& page, const std::string& png) {
  PageCheck check;
  const auto shot =
      RunCommand("bash " + std::string(WATERGS_SOURCE_DIR) +
                 "/scripts/screenshot_report.sh " + ShellQuote(page) + " " +
                 ShellQuote(png) + " 1100");
  if (shot.exit_code == 2) {
    check.skipped = true;
    return check;
  }
  if (shot.exit_code != 0) {
    check.problems.push_back("screenshot failed: " + shot.output);
    return check;
  }
  check.screenshot = png;
  std::istringstream console(ReadText(png + ".console.txt"));
  for (std::string line; std::getline(console, line);) {
    if (!line.empty()) check.problems.push_back("console: " + line);
  }
  const nlohmann::json probe = nlohmann::json::parse(ReadText(png + ".json"));
  const cv::Mat screen = cv::imread(png, cv::IMREAD_COLOR);
  if (screen.cols != 1100 || screen.rows != probe["height"].get<int>()) {
    check.problems.push_back("screenshot is not the whole page");
    return check;
  }
  for (const auto& element : probe["overflow"]) {
    check.problems.push_back("wider than its box: " +
                             element.get<std::string>());
  }
  const std::string html = ReadText(page);
  for (const auto& image : probe["images"]) {
    ++check.images;
    const std::string id = image["id"];
    if (!image["complete"].get<bool>() || image["natural_width"] == 0) {
      check.problems.push_back("image " + id + " not decoded");
      continue;
    }
    const cv::Rect box(int(std::lround(image["x"].get<double>())),
                       int(std::lround(image["y"].get<double>())),
                       int(std::lround(image["width"].get<double>())),
                       int(std::lround(image["height"].get<double>())));
    if (box.width < 4 || box.height < 4 ||
        (box & cv::Rect(0, 0, screen.cols, screen.rows)) != box) {
      check.problems.push_back("image " + id + " outside the screenshot");
      continue;
    }
    const cv::Mat shown = screen(box);
    cv::Scalar mean, deviation;
    cv::meanStdDev(shown, mean, deviation);
    if (std::max({deviation[0], deviation[1], deviation[2]}) < 2) {
      check.problems.push_back("image " + id + " is blank");
      continue;
    }
    const cv::Mat data = EmbeddedImage(html, id);
    if (data.empty()) {
      check.problems.push_back("image " + id + " has no PNG data");
      continue;
    }
    cv::Mat expected;
    cv::resize(data, expected, box.size(), 0, 0, cv::INTER_NEAREST);
    cv::Mat difference;
    cv::absdiff(shown, expected, difference);
    const cv::Scalar mean_difference = cv::mean(difference);
    const double worst =
        std::max({mean_difference[0], mean_difference[1], mean_difference[2]});
    check.worst_difference = std::max(check.worst_difference, worst);
    if (worst > 3) {
      check.problems.push_back("image " + id +
                               " on screen differs from its data by " +
                               std::to_string(worst));
    }
  }
  return check;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& line : lines) out += line + "\n";
  return out;
}

TEST(ReportScreenshot, ImagesDecodeWhereTheyStandAndTheConsoleStaysEmpty) {
  TempDir dir("report_screenshot");
  const Scene s = MakeScene(dir, "wm.ply");
  const std::string page = dir / "report.html";
  const auto run = RunCommand(
      WatergsBin() + " report --raw_path " + s.raw + " --input_path " + s.wm +
      " --workspace_path " + s.ws + " --decoder " + s.decoder +
      " --message hex:a5c3 --attacks identity,gn:0.01 --image_attacks "
      "jpeg:50 --show_views 2 --num_threads 2 --output_path " +
      page);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const PageCheck check = CheckInBrowser(page, dir / "shot.png");
  if (check.skipped) {
    GTEST_SKIP() << "no Chromium at /usr/bin/chromium (apt-get install "
                    "chromium; scripts/install_deps.sh --tests does): the "
                    "report's "
                    "browser check needs it";
  }
  EXPECT_EQ(check.images, 6u);
  EXPECT_TRUE(check.problems.empty()) << Join(check.problems);
  std::printf("images on screen vs their data: mean difference <= %.2f\n",
              check.worst_difference);

  // The check sees what it must: the same page with a script error, the
  // first image's data corrupted and the second image replaced by a blank
  // one of its size.
  std::string broken = ReadText(page);
  const std::string data = "src=\"data:image/png;base64,";
  const size_t first = broken.find(data) + data.size();
  broken.replace(first, 8, "AAAAAAAA");
  const size_t second = broken.find(data, first) + data.size();
  const size_t second_end = broken.find('"', second);
  const cv::Mat second_image = EmbeddedImage(ReadText(page), "wm-0");
  ASSERT_FALSE(second_image.empty());
  ImageRGB blank(second_image.cols, second_image.rows);
  std::fill(blank.data.begin(), blank.data.end(), 0.5f);
  broken.replace(second, second_end - second, Base64(EncodePng(blank)));
  broken.replace(broken.find("</main>"), 0,
                 "<script>not_a_function();</script>");
  const std::string broken_page = dir / "broken.html";
  AtomicWriteFile(broken_page, broken);
  const PageCheck flagged = CheckInBrowser(broken_page, dir / "broken.png");
  const std::string found = Join(flagged.problems);
  EXPECT_NE(found.find("console: "), std::string::npos) << found;
  EXPECT_NE(found.find("not_a_function"), std::string::npos) << found;
  EXPECT_NE(found.find("image raw-0 not decoded"), std::string::npos) << found;
  EXPECT_NE(found.find("image wm-0 is blank"), std::string::npos) << found;
  // Nothing else: the other four images pass.
  EXPECT_EQ(std::count_if(flagged.problems.begin(), flagged.problems.end(),
                          [](const std::string& problem) {
                            return problem.rfind("image ", 0) == 0;
                          }),
            2)
      << found;
}

}  // namespace
}  // namespace watergs
