// CLI tests of `watergs detect` (issue 24, item 3): renders of a watermarked
// model written as PNG files give "watermark present" for the owner's claim
// and each image the bits `extract` reads from the same camera; renders of
// the raw model do not; JSON; and each unusable input fails in one line
// naming the file. The owner's reading's registration index is cached
// beside the workspace and read back by the next call (issue 54, item 4).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "gaussian/formats/ply_io.h"
#include "gaussian/rasterizer.h"
#include "gaussian/render_conventions.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "tests/plugin/rendered_images.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"
#include "watermark/message.h"

namespace watergs {
namespace {

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kClaim = "hex:9c2e5b71a4d3";
const std::string kDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Writes `renders` as PNG files view_<k>.png in `folder`; returns it.
std::string WritePngs(const std::vector<ImageRGB>& renders,
                      const std::string& folder) {
  CreateDirectories(folder);
  for (size_t k = 0; k < renders.size(); ++k) {
    WriteImageFile(folder + "/view_" + std::to_string(k) + ".png", renders[k]);
  }
  return folder;
}

TEST(DetectCli, ReadsTheWatermarkFromRenderedImagesAsExtractDoes) {
  TempDir dir("detect_cli");
  testing::SyntheticModelOptions options;
  options.num_images = 6;
  options.width = 48;
  options.height = 36;
  GaussianModel raw;
  WorkspaceOptions wo;
  wo.workspace_path = testing::MakeRenderedWorkspace(dir / "ws", options, &raw);
  // A real embedding with the shipped decoder, short: small frames, no 3D
  // distortions, stopped once the check views read the claim.
  WritePly(dir / "raw.ply", raw);
  const auto embed = RunCommand(
      WatergsBin() + " embed --input_path " + (dir / "raw.ply") +
      " --workspace_path " + wo.workspace_path + " --decoder " + kDecoder +
      " --message " + kClaim + " --output_path " + (dir / "wm.ply") +
      " --iterations 500 --distortions none --crop_size 0 --densify off"
      " --reading blind --check_every 20 --check_views 6 --patience 1"
      " --num_threads 2");
  ASSERT_EQ(embed.exit_code, 0) << embed.output;
  const GaussianModel wm = ReadPly(dir / "wm.ply").model;
  const Workspace workspace = Workspace::Open(wo);
  std::unique_ptr<BitDecoder> decoder = LoadBitDecoder(kDecoder, Device::kCpu);
  const WorkspaceViews views(workspace);
  std::vector<RenderCamera> cameras;
  std::vector<std::string> names;
  for (size_t v = 0; v < views.NumViews(); ++v) {
    cameras.push_back(views.Camera(v));
    names.push_back(views.Name(v));
  }
  const std::string wm_pngs =
      WritePngs(testing::RenderViews(wm, workspace), dir / "wm_png");
  const std::string raw_pngs =
      WritePngs(testing::RenderViews(raw, workspace), dir / "raw_png");

  const std::string base = WatergsBin() + " detect --decoder " + kDecoder;
  const std::string json = dir / "detect.json";
  const auto present = RunCommand(base + " --image_path " + wm_pngs +
                                  " --message " + kClaim + " --json " + json);
  ASSERT_EQ(present.exit_code, 0) << present.output;
  EXPECT_NE(present.output.find("verdict: watermark present"),
            std::string::npos)
      << present.output;
  EXPECT_NE(present.output.find("single-image BER mean"), std::string::npos);
  const nlohmann::json j = ReadJson(json);
  EXPECT_EQ(j["command"], "detect");
  EXPECT_EQ(j["verdict"], "watermark present");
  EXPECT_EQ(j["num_bits"], 48);
  EXPECT_TRUE(j["view_ber"].contains("p90"));
  ASSERT_EQ(j["views"].size(), 6u);

  // Each image reads the bits extract reads from the same camera's render
  // (stored in 8 bits, as the file stores it), and the aggregate is the
  // same: the logits of the files are those of the quantised renders.
  const Bits claim_bits = ParseMessage(kClaim, 48);
  const ExtractionResult extracted = ExtractWatermark(
      *MakeCpuRasterizer(), wm, cameras, names, *decoder, &claim_bits,
      {0, 0, 0}, VerificationThresholds(), testing::Quantise8);
  ASSERT_EQ(extracted.views.size(), 6u);
  for (size_t v = 0; v < 6; ++v) {
    const auto& image = j["views"][v];
    EXPECT_EQ(image["name"], wm_pngs + "/view_" + std::to_string(v) + ".png");
    EXPECT_EQ(image["bit_errors"], extracted.views[v].bit_errors) << v;
    EXPECT_EQ(image["logits"].get<std::vector<float>>(),
              extracted.views[v].logits)
        << v;
  }
  // The single-image spread it reports, from the images' own bit errors:
  // the mean, and p90 as the smallest count that 90% of images do not
  // exceed.
  std::vector<int> errors;
  for (const auto& image : j["views"]) errors.push_back(image["bit_errors"]);
  double mean = 0;
  for (int e : errors) mean += e / 48.0 / errors.size();
  int p90 = 48;
  for (int candidate : errors) {
    const auto at_most = std::count_if(errors.begin(), errors.end(),
                                       [&](int e) { return e <= candidate; });
    if (10 * at_most >= 9 * int(errors.size())) p90 = std::min(p90, candidate);
  }
  EXPECT_NEAR(j["view_ber"]["mean"].get<double>(), mean, 1e-9);
  EXPECT_NEAR(j["view_ber"]["p90"].get<double>(), p90 / 48.0, 1e-9);
  EXPECT_EQ(j["recovered_bits"], BitsToString(extracted.recovered));
  EXPECT_EQ(j["p_value"], extracted.p_value);

  // The raw model's renders do not carry the claim.
  const auto absent =
      RunCommand(base + " --image_path " + raw_pngs + " --message " + kClaim);
  ASSERT_EQ(absent.exit_code, 0) << absent.output;
  EXPECT_EQ(absent.output.find("verdict: watermark present"), std::string::npos)
      << absent.output;
  EXPECT_NE(absent.output.find("verdict: "), std::string::npos);

  // Copies shared at half size: decoded at the render's width again they
  // read what the renders read, within a few bits.
  std::vector<ImageRGB> halves;
  for (const ImageRGB& render : testing::RenderViews(wm, workspace)) {
    halves.push_back(ResizeTo(render, 24, 18));
  }
  const std::string half_pngs = WritePngs(halves, dir / "half_png");
  const auto half = RunCommand(base + " --image_path " + half_pngs +
                               " --message " + kClaim + " --decode_width 48");
  ASSERT_EQ(half.exit_code, 0) << half.output;
  EXPECT_NE(half.output.find("verdict: watermark present"), std::string::npos)
      << half.output;
  testing::ExpectOneLineError(
      RunCommand(base + " --image_path " + half_pngs + " --decode_width -2"),
      "--decode_width");

  // Files and folders mixed, comma-separated; one line per image.
  const auto mixed =
      RunCommand(base + " --image_path " + raw_pngs + "/view_0.png," + wm_pngs +
                 " --message " + kClaim);
  ASSERT_EQ(mixed.exit_code, 0) << mixed.output;
  EXPECT_NE(mixed.output.find("detect: 7 images"), std::string::npos)
      << mixed.output;
}

// The lines of `output` that start with `prefix`.
std::vector<std::string> LinesStartingWith(const std::string& output,
                                           const std::string& prefix) {
  std::vector<std::string> lines;
  size_t start = 0;
  while (start < output.size()) {
    size_t end = output.find('\n', start);
    if (end == std::string::npos) end = output.size();
    const std::string line = output.substr(start, end - start);
    if (line.rfind(prefix, 0) == 0) lines.push_back(line);
    start = end + 1;
  }
  return lines;
}

// The files in `folder` (none if it does not exist).
std::vector<std::string> FilesIn(const std::string& folder) {
  std::vector<std::string> names;
  if (!std::filesystem::is_directory(folder)) return names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// The owner's reading indexes the workspace once: the first call builds the
// registration index and writes it to WS/detect_index/<key>.idx, the second
// reads it and gives the same reading to the last bit, writing nothing; a
// changed raw model is another key; a folder that cannot be written only
// warns; every call prints where its time went.
TEST(DetectCli, TheOwnersIndexIsCachedBesideTheWorkspaceAndReadBack) {
  TempDir dir("detect_cli_cache");
  // A synthetic workspace whose photos are renders of the raw model with
  // small Gaussians (a blob on each SfM point, where SIFT finds a feature),
  // and those renders as the images.
  testing::SyntheticModelOptions options;
  options.num_images = 6;
  options.num_points = 300;
  options.width = 160;
  options.height = 120;
  GaussianModel raw;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", options, &raw);
  for (float& s : raw.log_scales) s -= 1.0f;
  WritePly(dir / "raw.ply", raw);
  WorkspaceOptions wo;
  wo.workspace_path = ws;
  const Workspace workspace = Workspace::Open(wo);
  const std::vector<ImageRGB> renders = testing::RenderViews(raw, workspace);
  for (size_t v = 0; v < renders.size(); ++v) {
    WritePng(ws + "/images/" + workspace.ViewName(v), renders[v]);
  }
  WritePngs({renders[1], renders[3], renders[4]}, dir / "photos");
  const std::string pngs = dir / "photos";
  const std::string decoder = testing::WriteTinyDecoder(dir / "tiny.bin");
  const std::string base =
      WatergsBin() + " detect --decoder " + decoder + " --image_path " + pngs +
      " --message hex:a5c3" + " --raw_path " + (dir / "raw.ply") +
      " --workspace_path " + ws + " --index_renders 4 --num_threads 2";
  const std::string cache = ws + "/detect_index";

  const auto first = RunCommand(base + " --json " + (dir / "first.json"));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("detect: index written to " + cache + "/"),
            std::string::npos)
      << first.output;
  const std::vector<std::string> files = FilesIn(cache);
  ASSERT_EQ(files.size(), 1u);
  EXPECT_EQ(files[0].size(), 16u + 4u) << files[0];  // <key hex>.idx
  const std::vector<uint8_t> index = ReadFileBytes(cache + "/" + files[0]);
  const auto modified =
      std::filesystem::last_write_time(cache + "/" + files[0]);
  EXPECT_NE(first.output.find("detect: time: indexing "), std::string::npos);
  EXPECT_NE(first.output.find(" s (built), registration "), std::string::npos)
      << first.output;

  const auto second = RunCommand(base + " --json " + (dir / "second.json"));
  ASSERT_EQ(second.exit_code, 0) << second.output;
  EXPECT_NE(second.output.find("detect: index read from " + cache + "/" +
                               files[0] + " ("),
            std::string::npos)
      << second.output;
  EXPECT_EQ(second.output.find("index written"), std::string::npos);
  EXPECT_EQ(second.output.find("indexing renders"), std::string::npos);
  const std::vector<std::string> time_lines =
      LinesStartingWith(second.output, "detect: time: ");
  ASSERT_EQ(time_lines.size(), 1u) << second.output;
  EXPECT_NE(time_lines[0].find(" s (cached), registration "), std::string::npos)
      << time_lines[0];
  EXPECT_NE(time_lines[0].find(" over 3 images ("), std::string::npos)
      << time_lines[0];
  // Nothing else written: the one file, as it was.
  EXPECT_EQ(FilesIn(cache), files);
  EXPECT_EQ(ReadFileBytes(cache + "/" + files[0]), index);
  EXPECT_EQ(std::filesystem::last_write_time(cache + "/" + files[0]), modified);
  // The same reading, to the last bit: verdicts, bit errors, cameras,
  // logits.
  EXPECT_EQ(LinesStartingWith(second.output, "detect (owner's reading)"),
            LinesStartingWith(first.output, "detect (owner's reading)"));
  const nlohmann::json a = ReadJson(dir / "first.json");
  const nlohmann::json b = ReadJson(dir / "second.json");
  ASSERT_TRUE(a["owner"].contains("registrations"));
  int registered = 0;
  for (const auto& r : a["owner"]["registrations"])
    registered += r["registered"].get<bool>();
  EXPECT_GE(registered, 1) << a["owner"].dump();
  EXPECT_EQ(a["owner"], b["owner"]);
  EXPECT_EQ(a["views"], b["views"]);
  EXPECT_EQ(a["time"]["index"], "built");
  EXPECT_EQ(b["time"]["index"], "cached");
  EXPECT_EQ(b["time"]["index_file"], cache + "/" + files[0]);
  EXPECT_EQ(b["time"]["images"], 3);
  for (const char* figure : {"indexing_s", "registration_s", "refinement_s",
                             "decoding_s", "per_image_s", "total_s"}) {
    EXPECT_GE(b["time"][figure].get<double>(), 0) << figure;
  }

  // Another raw model (one Gaussian's colour changed): another key, a new
  // file beside the first.
  GaussianModel changed = raw;
  changed.sh_dc[0] += 0.01f;
  WritePly(dir / "raw.ply", changed);
  // (Without the pose refinement from here on: quicker.)
  const std::string quick = base + " --refine_pose 0";
  const auto third = RunCommand(quick);
  ASSERT_EQ(third.exit_code, 0) << third.output;
  EXPECT_NE(third.output.find("detect: index written to"), std::string::npos)
      << third.output;
  EXPECT_EQ(FilesIn(cache).size(), 2u);

  // A cache folder that cannot be created: one warning, the same reading.
  const std::string blocked = dir / "raw.ply/cache";
  const auto unwritable = RunCommand(quick + " --index_cache " + blocked);
  ASSERT_EQ(unwritable.exit_code, 0) << unwritable.output;
  EXPECT_EQ(LinesStartingWith(unwritable.output, "detect: warning: ").size(),
            1u)
      << unwritable.output;
  EXPECT_NE(unwritable.output.find("the index is not cached"),
            std::string::npos)
      << unwritable.output;
  EXPECT_EQ(LinesStartingWith(unwritable.output, "detect (owner's reading)"),
            LinesStartingWith(third.output, "detect (owner's reading)"));
  // Empty: no cache at all.
  const auto uncached = RunCommand(quick + " --index_cache \"\"");
  ASSERT_EQ(uncached.exit_code, 0) << uncached.output;
  EXPECT_EQ(uncached.output.find("detect: index "), std::string::npos)
      << uncached.output;
  EXPECT_EQ(FilesIn(cache).size(), 2u);
}

// The owner's reference follows the renderer the image came from
// (--reference_conventions auto, issue 54): a watergs render saved as PNG
// keeps watergs' reference and reads exactly as with
// --reference_conventions watergs; the same view rendered as
// gaussian-splats-3d renders it (web: SH degree 0 here, where the model's
// colour depends on the view) gets the web reference, which matches it
// better than watergs' does.
TEST(DetectCli, TheReferenceFollowsTheRendererTheImageCameFrom) {
  TempDir dir("detect_cli_conventions");
  testing::SyntheticModelOptions options;
  options.num_images = 6;
  options.num_points = 1000;
  options.width = 160;
  options.height = 120;
  GaussianModel raw;
  const std::string ws =
      testing::MakeRenderedWorkspace(dir / "ws", options, &raw);
  for (float& s : raw.log_scales) s -= 1.0f;
  // View-dependent colour (SH degree 1), which the web viewer leaves out.
  ASSERT_EQ(raw.sh_degree, 1);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> shade(-0.3f, 0.3f);
  for (float& c : raw.sh_rest) c = shade(rng);
  WritePly(dir / "raw.ply", raw);
  WorkspaceOptions wo;
  wo.workspace_path = ws;
  const Workspace workspace = Workspace::Open(wo);
  const std::vector<ImageRGB> renders = testing::RenderViews(raw, workspace);
  for (size_t v = 0; v < renders.size(); ++v) {
    WritePng(ws + "/images/" + workspace.ViewName(v), renders[v]);
  }
  RenderOptions web_options;
  web_options.conventions = FindRenderConventions("web", "test").conventions;
  ImageRGB web;
  MakeCpuRasterizer()->Forward(raw, workspace.ViewCamera(3), web_options, &web,
                               nullptr);
  for (float& v : web.data) v = std::clamp(v, 0.f, 1.f);
  CreateDirectories(dir / "shots");
  const std::string own = dir / "shots/a_watergs.png";
  const std::string viewer = dir / "shots/b_web.png";
  WritePng(own, renders[1]);
  WritePng(viewer, web);
  const std::string decoder = testing::WriteTinyDecoder(dir / "tiny.bin");
  const std::string base =
      WatergsBin() + " detect --decoder " + decoder + " --image_path " +
      (dir / "shots") + " --message hex:a5c3 --raw_path " + (dir / "raw.ply") +
      " --workspace_path " + ws + " --index_renders 4 --num_threads 2";

  const auto chosen = RunCommand(base + " --json " + (dir / "auto.json"));
  ASSERT_EQ(chosen.exit_code, 0) << chosen.output;
  const std::vector<std::string> lines =
      LinesStartingWith(chosen.output, "detect (owner's reading): " + own);
  ASSERT_EQ(lines.size(), 1u) << chosen.output;
  EXPECT_NE(lines[0].find("reference watergs at "), std::string::npos)
      << lines[0];
  EXPECT_NE(lines[0].find("(web "), std::string::npos) << lines[0];
  const std::vector<std::string> web_lines =
      LinesStartingWith(chosen.output, "detect (owner's reading): " + viewer);
  ASSERT_EQ(web_lines.size(), 1u) << chosen.output;
  EXPECT_NE(web_lines[0].find("reference web at "), std::string::npos)
      << web_lines[0];
  const nlohmann::json a = ReadJson(dir / "auto.json");
  const auto& registrations = a["owner"]["registrations"];
  ASSERT_EQ(registrations.size(), 2u);
  ASSERT_TRUE(registrations[0]["registered"].get<bool>()) << a.dump();
  ASSERT_TRUE(registrations[1]["registered"].get<bool>()) << a.dump();
  const auto& mine = registrations[0]["reference"];
  const auto& theirs = registrations[1]["reference"];
  EXPECT_EQ(mine["conventions"], "watergs");
  EXPECT_EQ(theirs["conventions"], "web");
  EXPECT_GT(mine["psnr"]["watergs"].get<double>(),
            mine["psnr"]["web"].get<double>() + 3);
  EXPECT_GT(theirs["psnr"]["web"].get<double>(),
            theirs["psnr"]["watergs"].get<double>() + 3);

  // Only watergs' conventions: the watergs render reads the same logits
  // and camera as under auto; the web screenshot gets watergs' reference.
  const auto fixed = RunCommand(base + " --reference_conventions watergs" +
                                " --json " + (dir / "watergs.json"));
  ASSERT_EQ(fixed.exit_code, 0) << fixed.output;
  const nlohmann::json b = ReadJson(dir / "watergs.json");
  EXPECT_EQ(b["owner"]["registrations"][0]["camera"],
            registrations[0]["camera"]);
  EXPECT_EQ(b["owner"]["views"][0]["logits"], a["owner"]["views"][0]["logits"]);
  EXPECT_EQ(b["owner"]["registrations"][1]["reference"]["conventions"],
            "watergs");
  EXPECT_EQ(
      LinesStartingWith(fixed.output, "detect (owner's reading): " + viewer)[0]
          .find("reference web"),
      std::string::npos);

  ExpectOneLineError(RunCommand(base + " --reference_conventions webgl"),
                     "--reference_conventions: unknown render conventions "
                     "'webgl' (one of watergs, web, playcanvas)");
}

TEST(DetectCli, RefusesUnusableInputInOneLineNamingTheFile) {
  TempDir dir("detect_cli_errors");
  const std::string ok = dir / "ok.png";
  cv::Mat noise(40, 40, CV_8UC3);
  cv::randu(noise, 0, 256);
  ASSERT_TRUE(cv::imwrite(ok, noise));
  const std::string base = WatergsBin() + " detect --decoder " + kDecoder;
  ASSERT_EQ(RunCommand(base + " --image_path " + ok).exit_code, 0);

  const std::string text = dir / "notes.png";
  std::ofstream(text) << "not an image\n";
  ExpectOneLineError(RunCommand(base + " --image_path " + text),
                     text + ": cannot decode");
  std::vector<uchar> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", noise, bytes));
  const std::string truncated = dir / "cut.jpg";
  std::ofstream(truncated, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size() / 2);
  ExpectOneLineError(RunCommand(base + " --image_path " + ok + "," + truncated),
                     truncated + ": truncated JPEG");
  const std::string tiny = dir / "tiny.png";
  ASSERT_TRUE(cv::imwrite(tiny, noise(cv::Rect(0, 0, 3, 3))));
  ExpectOneLineError(RunCommand(base + " --image_path " + tiny),
                     tiny + ": feature decoder: input of 3x3");
  const std::string grey = dir / "grey.png";
  ASSERT_TRUE(
      cv::imwrite(grey, cv::Mat(40, 40, CV_8UC3, cv::Scalar::all(128))));
  ExpectOneLineError(RunCommand(base + " --image_path " + grey),
                     grey + ": uniform image (one colour) carries no signal");
  const std::string huge = dir / "huge.png";
  cv::Mat wide(160, 8200, CV_8UC3);
  cv::randu(wide, 0, 256);
  ASSERT_TRUE(cv::imwrite(huge, wide));
  ExpectOneLineError(RunCommand(base + " --image_path " + huge),
                     huge + ": is 8200x160, far larger than renders");
  const auto resized =
      RunCommand(base + " --image_path " + huge + " --max_side 410");
  ASSERT_EQ(resized.exit_code, 0) << resized.output;
  EXPECT_NE(resized.output.find("(410x8)"), std::string::npos)
      << resized.output;
  ExpectOneLineError(RunCommand(base + " --image_path " + ok +
                                " --message hex:00112233445566"),
                     "needs 56 bits but the decoder reads 48");
  ExpectOneLineError(RunCommand(WatergsBin() + " detect --decoder " + ok +
                                " --image_path " + ok),
                     ok + ": ");
  ExpectOneLineError(RunCommand(base + " --image_path " + (dir / "nope.png")),
                     dir / "nope.png: file not found");
  CreateDirectories(dir / "empty");
  ExpectOneLineError(RunCommand(base + " --image_path " + (dir / "empty")),
                     dir / "empty: no .png or .jpg images");
}

}  // namespace
}  // namespace watergs
