// `watergs null_calibration`: how often unmarked views pass the verdict.
// Reads the per-view logits that `extract --json` and `detect --json` write
// for unmarked models and images (one group per file: a scene), decodes
// random crops of photo folders (one group per folder), and tests them
// against the owner's message as a fixed claim and under many keys, single
// views and aggregates of views: the empirical false-positive rate next to
// the binomial one at each nominal rate (docs/verification.md).
#include "watermark/null_calibration.h"

#include <omp.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "gaussian/util/text_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/message.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// The views' logits of an extract/detect JSON file; `owner`: those of the
// owner's reading (extract --raw_path), each view minus the raw model's.
NullGroup ReadLogitsFile(const std::string& path, int num_bits, bool owner) {
  std::ifstream in(path);
  if (!in) FailAt(path, "cannot open the logits file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    FailAt(path, std::string("not JSON: ") + e.what());
  }
  if (owner) {
    if (!j.is_object() || !j.contains("owner") || !j["owner"].is_object()) {
      FailAt(path, "no \"owner\" reading: expected extract --raw_path --json");
    }
    j = j["owner"];
  }
  if (!j.is_object() || !j.contains("views") || !j["views"].is_array()) {
    FailAt(path, "no \"views\" array: expected extract or detect --json");
  }
  NullGroup group{fs::path(path).stem().string(), {}};
  for (const nlohmann::json& view : j["views"]) {
    if (!view.is_object() || !view.contains("logits") ||
        !view["logits"].is_array()) {
      FailAt(path,
             "a view without \"logits\" (written before extract stored "
             "them? rerun extract --json)");
    }
    std::vector<float> logits;
    for (const nlohmann::json& v : view["logits"]) {
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        FailAt(path, "a logit that is not a finite number");
      }
      logits.push_back(v.get<float>());
    }
    if (static_cast<int>(logits.size()) != num_bits) {
      FailAt(path, "a view has " + std::to_string(logits.size()) +
                       " logits; the decoder reads " +
                       std::to_string(num_bits) + " bits");
    }
    group.logits.push_back(std::move(logits));
  }
  if (group.logits.empty()) FailAt(path, "holds no view");
  return group;
}

// `crops` random crops of the folder's photos, decoded.
NullGroup DecodePhotoCrops(const std::string& folder, BitDecoder& decoder,
                           int crop, int crops, uint32_t seed) {
  const std::vector<cv::Mat> photos = LoadPhotoFolder(folder);
  const std::vector<ImageRGB> images =
      SamplePhotoCrops(photos, crop, crops, seed);
  NullGroup group{fs::path(folder).filename().string() + " crops", {}};
  group.logits.resize(images.size());
  ProgressBar progress("null_calibration: decoding " + folder,
                       static_cast<int64_t>(images.size()));
  for (size_t i = 0; i < images.size(); ++i) {
    group.logits[i] = decoder.Logits(images[i]);
    progress.Update(static_cast<int64_t>(i + 1));
  }
  progress.Finish();
  return group;
}

std::vector<int> ParseSizes(const std::string& text) {
  std::vector<int> sizes;
  for (const std::string& entry : SplitList(text)) {
    const std::optional<double> v = ParseFiniteDouble(entry);
    if (!v || *v < 1 || *v != int(*v)) {
      Fail("--aggregate: `" + entry + "` is not a view count >= 1");
    }
    sizes.push_back(int(*v));
  }
  if (sizes.empty()) Fail("--aggregate: no view count");
  return sizes;
}

int RunNullCalibration(int argc, char** argv) {
  std::string decoder_path, logits_list, image_list, aggregate = "1,6";
  std::string message = "text:WGS-26", markdown_path, json_path;
  std::string reading = "blind";
  int crop = 128, crops = 2000, keys = 1000, single_keys = 3;
  int aggregates = 2000, seed = 0, num_threads = 0;
  OptionParser parser(
      "null_calibration",
      "Measures how often unmarked views pass the verdict: the logits of "
      "extract/detect --json files (one group each, e.g. free viewpoints of "
      "an unmarked model) and random crops of photo folders are tested "
      "against the message as a fixed claim, under single keys and under "
      "--keys keys, single views and aggregates of views; prints the "
      "empirical rate next to the binomial one at nominal 1e-2 .. 1e-6.");
  decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &decoder_path, kDecoderHelp);
  parser.Add("logits", &logits_list,
             "extract/detect --json files of unmarked views, comma-separated");
  parser.Add("reading", &reading,
             "Logits read from the files: blind (each view's own) or owner "
             "(the owner's reading of extract --raw_path: minus the raw "
             "model's)");
  parser.Add("image_path", &image_list,
             "Folders of unmarked photos, comma-separated (random crops)");
  parser.Add("crop", &crop, "Side of the photo crops");
  parser.Add("crops", &crops, "Crops per photo folder");
  parser.Add("message", &message,
             std::string("The owner's message: ") + kMessageFormats);
  parser.Add("keys", &keys, "Keys of the keyed family");
  parser.Add("single_keys", &single_keys,
             "Keys also reported one by one (an owner holds one)");
  parser.Add("aggregate", &aggregate,
             "Views averaged per read, comma-separated (1 = single views)");
  parser.Add("aggregates", &aggregates,
             "Random sets of views drawn per group for each count > 1");
  parser.Add("seed", &seed, "Seed of the crops and the sets of views");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  parser.Add("markdown", &markdown_path, "Write the tables here");
  parser.Add("json", &json_path, "Write the figures as JSON here");
  if (!parser.Parse(argc, argv)) return 0;
  if (logits_list.empty() && image_list.empty()) {
    Fail("null_calibration: give --logits and/or --image_path");
  }
  if (reading != "blind" && reading != "owner") {
    Fail("null_calibration: --reading blind or owner");
  }
  if (crop < 16 || crops < 1) Fail("--crop must be >= 16 and --crops >= 1");
  if (keys < 1 || single_keys < 0 || single_keys > keys) {
    Fail("--keys must be >= 1 and --single_keys in [0, --keys]");
  }
  if (aggregates < 1) Fail("--aggregates must be >= 1");
  if (num_threads > 0) omp_set_num_threads(num_threads);
  if (!markdown_path.empty()) CheckOutputFile(markdown_path);
  if (!json_path.empty()) CheckOutputFile(json_path);
  NullCalibrationOptions options;
  options.aggregate_sizes = ParseSizes(aggregate);
  options.aggregates_per_group = aggregates;
  options.seed = uint64_t(seed);

  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(decoder_path, parser.device());
  const int num_bits = decoder->NumBits();
  const Bits bits = ParseMessage(message, num_bits);
  std::vector<NullGroup> groups;
  for (const std::string& path : SplitList(logits_list)) {
    groups.push_back(ReadLogitsFile(path, num_bits, reading == "owner"));
  }
  for (const std::string& folder : SplitList(image_list)) {
    groups.push_back(
        DecodePhotoCrops(folder, *decoder, crop, crops, uint32_t(seed)));
  }
  std::vector<NullClaim> claims = {{message + ", unkeyed", {bits}}};
  const NullClaim family =
      KeyedClaims(message + ", " + std::to_string(keys) + " keys", bits, keys);
  for (int k = 0; k < single_keys; ++k) {
    claims.push_back(
        {message + ", key " + std::to_string(k), {family.bits[size_t(k)]}});
  }
  claims.push_back(family);
  const NullCalibration calibration = CalibrateNull(groups, claims, options);
  const std::string markdown = NullCalibrationToMarkdown(calibration);
  std::cout << markdown;
  if (!markdown_path.empty()) AtomicWriteFile(markdown_path, markdown);
  if (!json_path.empty()) {
    AtomicWriteFile(
        json_path,
        WithProvenance(NullCalibrationToJson(calibration), 1, argc, argv));
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(null_calibration,
                "Measures the verdict's false-positive rate on unmarked views",
                watergs::RunNullCalibration);
