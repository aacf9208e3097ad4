#include "plugin/colmap_workflow.h"

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <set>
#include <utility>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "plugin/colmap_database.h"
#include "plugin/image_header.h"
#include "plugin/model_analyzer.h"
#include "plugin/reconstruction_io.h"
#include "plugin/report_evidence.h"
#include "plugin/sift_matching.h"
#include "watermark/image_reading.h"

namespace watergs {
namespace {

// What a stage's marker records: its command with the workspace's path as
// "$WORKSPACE", so that a workspace moved or copied elsewhere (a backup, a
// test fixture) resumes instead of reading as "other settings".
std::string StageMarker(const std::string& command,
                        const std::filesystem::path& ws) {
  std::string text = command;
  const std::string path = ws.string();
  for (size_t at = text.find(path); !path.empty() && at != std::string::npos;
       at = text.find(path, at + 10)) {
    text.replace(at, path.size(), "$WORKSPACE");
  }
  return text + "\n";
}

namespace fs = std::filesystem;

// Output of `command` (stdout and stderr) and its exit status.
struct Captured {
  std::string output;
  int status = -1;
};

Captured Capture(const std::string& command) {
  Captured c;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return c;
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof buffer, pipe))
    c.output.append(buffer, n);
  c.status = pclose(pipe);
  return c;
}

// One COLMAP stage: the command, where its output goes, and how a progress
// line reads ("Processed file [3/48]" -> 3 of 48).
struct Stage {
  std::string name, command, log_path;
  std::regex progress;
  // Steps done and total from a match (total 0: keep the stage's own).
  std::function<std::pair<int64_t, int64_t>(const std::smatch&)> count;
  int64_t total = 0;
  // Run in this process instead of `command` (which then names the work
  // for the stage's marker).
  std::function<void()> in_process;
  // A command that did this stage and the next in one (COLMAP's own matcher
  // before watergs matched on the CPU): its marker counts for both.
  std::string former_command;
};

// Runs `stage`, its output to its log, a progress bar from its lines.
void RunStage(const Stage& stage) {
  std::ofstream log(stage.log_path);
  if (!log) Fail(stage.log_path + ": cannot write the stage's log");
  log << "$ " << stage.command << "\n";
  if (stage.in_process) {
    log.close();
    stage.in_process();
    return;
  }
  FILE* pipe = popen((stage.command + " 2>&1").c_str(), "r");
  if (!pipe) Fail("reconstruct: cannot start " + stage.command);
  // Made at the first progress line: the exhaustive matcher's total is only
  // known then.
  std::unique_ptr<ProgressBar> bar;
  std::string line, last;
  int c = 0;
  while ((c = fgetc(pipe)) != EOF) {
    if (c != '\n' && c != '\r') {
      line.push_back(char(c));
      continue;
    }
    if (line.empty()) continue;
    log << line << "\n";
    std::smatch m;
    if (std::regex_search(line, m, stage.progress)) {
      const auto [done, total] = stage.count(m);
      const int64_t steps =
          std::max<int64_t>(1, stage.total > 0 ? stage.total : total);
      if (!bar)
        bar =
            std::make_unique<ProgressBar>("reconstruct: " + stage.name, steps);
      bar->Update(std::min(done, steps));
    }
    last = line;
    line.clear();
  }
  const int status = pclose(pipe);
  log.flush();
  if (status != 0) {
    Fail("reconstruct: colmap " + stage.name + " failed (" +
         (last.empty() ? std::string("no output") : last) + "); log " +
         stage.log_path);
  }
  if (bar) bar->Finish();
}

int ToInt(const std::ssub_match& m) { return std::stoi(m.str()); }

// The image pairs (in name order) that `matcher` compares among `n` photos.
std::vector<std::pair<int, int>> MatchedPairs(const std::string& matcher,
                                              int n) {
  return matcher == "sequential" ? SequentialPairs(n, kSequentialOverlap, true)
                                 : ExhaustivePairs(n);
}

// Every photo's size and EXIF camera; error (one line) for a photo that does
// not decode.
std::vector<PhotoDescription> DescribePhotos(
    const std::vector<std::string>& photos) {
  std::vector<PhotoDescription> described(photos.size());
  for (size_t k = 0; k < photos.size(); ++k) {
    // Decoded (reduced by 8, cheap) so that a broken photo stops the run
    // before anything is written.
    const cv::Mat image = cv::imread(photos[k], cv::IMREAD_REDUCED_GRAYSCALE_8);
    if (image.empty()) FailAt(photos[k], "not a readable image");
    PhotoDescription& d = described[k];
    if (ReadImageHeaderSize(photos[k], &d.width, &d.height)) {
      d.exif = ReadExifCamera(photos[k]);
    } else {
      // Size not known exactly (the reduced decode rounds): a camera of
      // its own, never shared.
      d.width = image.cols * 8;
      d.height = image.rows * 8;
    }
  }
  return described;
}

// The names (in the workspace's images/) of photos that share a camera, in
// groups of two or more.
std::vector<std::vector<std::string>> SharedCameraGroups(
    const std::vector<std::string>& photos, const PhotoCameras& cameras) {
  std::vector<std::vector<std::string>> groups(cameras.num_groups);
  for (size_t k = 0; k < photos.size(); ++k) {
    groups[cameras.group[k]].push_back(fs::path(photos[k]).filename().string());
  }
  groups.erase(std::remove_if(groups.begin(), groups.end(),
                              [](const auto& g) { return g.size() < 2; }),
               groups.end());
  return groups;
}

// Keeps the model with the most registered images as sparse/0; returns it.
std::string KeepLargestModel(const std::string& sparse) {
  std::string best;
  size_t best_images = 0;
  for (const auto& entry : fs::directory_iterator(sparse)) {
    if (!entry.is_directory()) continue;
    const Reconstruction r = ReadReconstruction(entry.path().string());
    const size_t n = AnalyzeModel(r).num_reg_images;
    if (n > best_images) best = entry.path().string(), best_images = n;
  }
  if (best.empty()) Fail("reconstruct: the mapper wrote no model in " + sparse);
  const std::string zero = (fs::path(sparse) / "0").string();
  if (fs::path(best) != fs::path(zero)) {
    const std::string aside = (fs::path(sparse) / "0_smaller").string();
    fs::rename(zero, aside);
    fs::rename(best, zero);
    fs::rename(aside, best);
  }
  return zero;
}

// COLMAP's own matcher for `plan` (blocks of 10 photos in the exhaustive
// one, COLMAP defaults to 50, so that the demo's 48 show progress).
std::string ColmapMatcherCommand(const ColmapPlan& plan,
                                 const std::string& colmap,
                                 const std::string& db) {
  const std::string common =
      " --database_path " + db + " --SiftMatching.use_gpu " +
      (plan.use_gpu ? "1" : "0") + " --SiftMatching.num_threads " +
      std::to_string(plan.num_threads);
  if (plan.matcher == "sequential") {
    return colmap + " sequential_matcher" + common +
           " --SequentialMatching.overlap " +
           std::to_string(kSequentialOverlap) +
           " --SequentialMatching.loop_detection 0";
  }
  return colmap + " exhaustive_matcher" + common +
         " --ExhaustiveMatching.block_size 10";
}

// Matches every pair of `plan`'s matcher among the database's images, on
// `plan.num_threads` threads with a progress bar, into a match list that
// `colmap matches_importer --match_type raw` reads (written atomically).
void WriteExactMatches(const std::string& database, const ColmapPlan& plan,
                       const std::string& out_path) {
  const std::vector<DatabaseImage> images = ReadDatabaseImages(database);
  const std::vector<std::pair<int, int>> pairs =
      MatchedPairs(plan.matcher, int(images.size()));
  std::vector<FeatureMatches> matches(pairs.size());
  ProgressBar bar("reconstruct: matching", int64_t(pairs.size()));
  const int64_t chunk = 4 * std::max(1, plan.num_threads);
  for (int64_t start = 0; start < int64_t(pairs.size()); start += chunk) {
    const int64_t end = std::min<int64_t>(start + chunk, pairs.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(plan.num_threads)
    for (int64_t k = start; k < end; ++k) {
      matches[k] = MatchSiftDescriptors(images[pairs[k].first].descriptors,
                                        images[pairs[k].second].descriptors);
    }
    bar.Update(end);
  }
  std::string text;
  for (size_t k = 0; k < pairs.size(); ++k) {
    text +=
        images[pairs[k].first].name + " " + images[pairs[k].second].name + "\n";
    for (const auto& [i, j] : matches[k]) {
      text += std::to_string(i) + " " + std::to_string(j) + "\n";
    }
    text += "\n";
  }
  AtomicWriteFile(out_path, text);
  bar.Finish();
}

// The three COLMAP stages of `plan` for the workspace `ws` (photos in
// ws/images, `n` of them), each with its progress line.
std::vector<Stage> ColmapStages(const ColmapPlan& plan,
                                const std::string& colmap_binary,
                                const fs::path& ws, int64_t n) {
  const std::string colmap = ShellQuote(colmap_binary);
  const fs::path images = ws / "images";
  const std::string db = ShellQuote((ws / "database.db").string());
  const std::string t = std::to_string(plan.num_threads),
                    g = plan.use_gpu ? "1" : "0";
  const auto one_of = [](const std::smatch& m) {
    return std::pair<int64_t, int64_t>(ToInt(m[1]), ToInt(m[2]));
  };
  std::vector<Stage> stages;
  stages.push_back(
      {"features",
       colmap + " feature_extractor --database_path " + db + " --image_path " +
           ShellQuote(images.string()) + " --ImageReader.single_camera " +
           (plan.single_camera ? "1" : "0") +
           (plan.camera_per_photo ? " --ImageReader.single_camera_per_image 1"
                                  : "") +
           " --SiftExtraction.use_gpu " + g + " --SiftExtraction.num_threads " +
           t + " --SiftExtraction.max_num_features " +
           std::to_string(plan.max_features),
       "",
       std::regex(R"(Processed file \[(\d+)/(\d+)\])"),
       one_of,
       n,
       {},
       {}});
  if (plan.exact_matching) {
    const fs::path matches = ws / ".reconstruct" / "matches.txt";
    Stage match{"matching",
                "watergs exact SIFT matching, " + plan.matcher +
                    " pairs (max_ratio 0.8, max_distance 0.7, cross-check): " +
                    (ws / "database.db").string() + " -> " + matches.string(),
                "",
                std::regex("$^"),
                nullptr,
                0,
                {},
                {}};
    match.in_process = [plan, ws, matches] {
      WriteExactMatches((ws / "database.db").string(), plan, matches.string());
    };
    match.former_command = ColmapMatcherCommand(plan, colmap, db);
    stages.push_back(match);
    // matches_importer prints "a.jpg - b.jpg" per pair it verifies.
    auto verified = std::make_shared<int64_t>(0);
    stages.push_back({"verification",
                      colmap + " database_cleaner --database_path " + db +
                          " --type matches && " + colmap +
                          " matches_importer --database_path " + db +
                          " --match_list_path " + ShellQuote(matches.string()) +
                          " --match_type raw --SiftMatching.use_gpu 0"
                          " --SiftMatching.num_threads " +
                          t,
                      "",
                      std::regex(R"(^\S.* - \S.*$)"),
                      [verified](const std::smatch&) {
                        return std::pair<int64_t, int64_t>(++*verified, 0);
                      },
                      int64_t(MatchedPairs(plan.matcher, int(n)).size()),
                      {},
                      {}});
  } else if (plan.matcher == "sequential") {
    stages.push_back({"matching",
                      ColmapMatcherCommand(plan, colmap, db),
                      "",
                      std::regex(R"(Matching image \[(\d+)/(\d+)\])"),
                      one_of,
                      n,
                      {},
                      {}});
  } else {
    stages.push_back(
        {"matching",
         ColmapMatcherCommand(plan, colmap, db),
         "",
         std::regex(R"(Matching block \[(\d+)/(\d+), (\d+)/(\d+)\])"),
         [](const std::smatch& m) {
           const int64_t cols = ToInt(m[4]);
           return std::pair<int64_t, int64_t>(
               (ToInt(m[1]) - 1) * cols + ToInt(m[3]), ToInt(m[2]) * cols);
         },
         0,
         {},
         {}});
  }
  stages.push_back(
      {"mapping",
       colmap + " mapper --database_path " + db + " --image_path " +
           ShellQuote(images.string()) + " --output_path " +
           ShellQuote((ws / "sparse").string()) + " --Mapper.num_threads " + t,
       "",
       std::regex(R"(Registering image #\d+ \((\d+)\))"),
       [](const std::smatch& m) {
         return std::pair<int64_t, int64_t>(ToInt(m[1]), 0);
       },
       n,
       {},
       {}});
  return stages;
}

}  // namespace

std::vector<std::string> ListPhotos(const std::string& image_path) {
  return ListImageFiles(image_path, false);
}

bool NamedInCaptureOrder(const std::vector<std::string>& photos) {
  // A prefix without digits, then digits with separators: IMG_0001,
  // frame_00042, DJI_20200223_163016_842 (a timestamp).
  static const std::regex numbered(R"(^([^0-9]*)([0-9][0-9_.\-]*)$)");
  std::string prefix;
  std::set<std::string> numbers;
  for (const std::string& photo : photos) {
    const std::string stem = fs::path(photo).stem().string();
    std::smatch m;
    if (!std::regex_match(stem, m, numbered)) return false;
    if (numbers.empty()) prefix = m[1].str();
    if (m[1].str() != prefix) return false;
    // 0042 and 42 are one number.
    const std::string digits = m[2].str();
    const size_t first = digits.find_first_not_of('0');
    if (!numbers.insert(first == std::string::npos ? "0" : digits.substr(first))
             .second) {
      return false;
    }
  }
  return true;
}

namespace {

// "~4 min on 2 threads, estimated ...": exact matching and verification at
// 2,048 features (0.055 + 0.015 CPU-seconds a pair on the demo, 2 cores).
// The text says where the per-pair cost came from, so a user does not read
// it as measured on their photos or machine.
std::string MatchingTimeEstimate(int64_t pairs, int threads) {
  const double minutes = pairs * 0.07 / std::max(1, threads) / 60;
  char text[160];
  std::snprintf(text, sizeof(text),
                "~%.0f min on %d threads, an estimate from the demo scene's "
                "0.07 CPU-s a pair on a 2-core machine",
                std::max(1.0, minutes), threads);
  return text;
}

// The plan's line on cameras: how many, and why.
std::string CamerasReason(const PhotoCameras& cameras, int num_photos,
                          bool in_capture_order) {
  if (cameras.num_groups <= 1) {
    return std::string("one camera (photos share one size") +
           (cameras.num_exif_cameras == 1 ? " and EXIF camera)" : ")");
  }
  const std::string why =
      in_capture_order ? "" : "photos in no order may come from many cameras; ";
  if (cameras.num_exif_cameras == 0) {
    return "a camera per photo (" + why + "no photo names its camera in EXIF)";
  }
  return std::to_string(cameras.num_groups) + " cameras for " +
         std::to_string(num_photos) +
         " photos, one per EXIF camera and size (" + why + cameras.summary +
         ")";
}

}  // namespace

ColmapPlan PlanReconstruction(int num_photos, int num_threads, bool gpu_sift,
                              const PhotoCameras& cameras,
                              const ReconstructOptions& options,
                              bool names_with_spaces, bool in_capture_order) {
  ColmapPlan plan;
  plan.num_threads = num_threads;
  plan.use_gpu = gpu_sift;
  plan.single_camera = cameras.num_groups <= 1;
  plan.camera_per_photo = !plan.single_camera;
  const int64_t pairs = int64_t(num_photos) * (num_photos - 1) / 2;
  plan.matcher = options.matcher != "auto" ? options.matcher
                 : !in_capture_order || num_photos <= options.sequential_above
                     ? "exhaustive"
                     : "sequential";
  const int64_t sequential_pairs =
      int64_t(SequentialPairs(num_photos, kSequentialOverlap, true).size());
  plan.reasons.push_back(
      "matcher " + plan.matcher + ": " + std::to_string(num_photos) +
      " photos, " +
      std::to_string(plan.matcher == "exhaustive" ? pairs : sequential_pairs) +
      " pairs" +
      (options.matcher != "auto" ? " (--matcher)"
       : !in_capture_order       ? " (names in no capture order: every pair, " +
                                 MatchingTimeEstimate(pairs, num_threads) + ")"
       : plan.matcher == "exhaustive"
           ? " (every pair up to " + std::to_string(options.sequential_above) +
                 " photos named in capture order: sequential matching placed "
                 "part of the demo's photos wrongly, on repetitive texture)"
           : " (over " + std::to_string(options.sequential_above) +
                 " photos named in capture order: each with its 9 next in "
                 "name order and those 2^k ahead, as COLMAP's sequential "
                 "matcher)"));

  plan.max_features = options.max_features > 0 ? options.max_features
                      : gpu_sift               ? 8192
                                               : 2048;
  plan.reasons.push_back(
      "features " + std::to_string(plan.max_features) + " an image" +
      (options.max_features > 0 ? " (--max_features)"
       : gpu_sift               ? " (GPU SIFT)"
                  : " (CPU: a quarter of COLMAP's 8,192, for matching "
                    "time; docs/reconstruct.md)"));
  plan.reasons.push_back(std::string("SIFT on the ") +
                         (gpu_sift ? "GPU" : "CPU") + ", " +
                         std::to_string(num_threads) + " threads, " +
                         CamerasReason(cameras, num_photos, in_capture_order));
  plan.exact_matching = !gpu_sift && !names_with_spaces;
  plan.reasons.push_back(
      plan.exact_matching
          ? "matching on the CPU: exact nearest neighbours in watergs, "
            "verified by COLMAP (COLMAP 3.8's CPU matcher, slower, builds a "
            "k-d tree per pair)"
      : gpu_sift ? "matching: COLMAP's GPU matcher"
                 : "matching: COLMAP's CPU matcher (a photo's name holds a "
                   "space, which COLMAP's match list cannot name)");
  return plan;
}

namespace {

// COLMAP 3.8 extracts a camera per photo; the photos of one EXIF camera and
// size then share one in database.db, before matching and mapping.
void ShareCamerasInDatabase(const fs::path& ws,
                            const std::vector<std::string>& photos,
                            const PhotoCameras& cameras) {
  if (cameras.num_groups <= 1) return;
  const auto groups = SharedCameraGroups(photos, cameras);
  if (groups.empty()) return;
  const SharedCameras shared =
      ShareCameras((ws / "database.db").string(), groups);
  for (const std::string& name : shared.missing) {
    std::printf(
        "reconstruct: warning: %s is not in database.db (COLMAP's "
        "extractor skipped it): left out of the cameras shared\n",
        name.c_str());
  }
  std::printf(
      "reconstruct: cameras: %d in database.db (photos of one EXIF "
      "camera and size share one)\n",
      shared.num_cameras);
  std::fflush(stdout);
}

}  // namespace

void RunReconstruction(const ReconstructOptions& o) {
  if (o.workspace_path.empty()) Fail("reconstruct: --workspace_path is empty");
  const fs::path ws = fs::absolute(o.workspace_path);
  const fs::path images = ws / "images";
  const fs::path photos_dir =
      fs::absolute(o.image_path.empty() ? images : fs::path(o.image_path));
  const Captured version = Capture(ShellQuote(o.colmap) + " -h");
  if (version.output.find("COLMAP") == std::string::npos) {
    Fail("reconstruct: no COLMAP binary `" + o.colmap +
         "` (install it: apt-get install colmap, or give --colmap PATH)");
  }
  const bool cuda_colmap =
      version.output.find("with CUDA") != std::string::npos;
  const std::vector<std::string> photos = ListPhotos(photos_dir.string());
  if (photos.size() < 3) {
    FailAt(photos_dir.string(), "holds " + std::to_string(photos.size()) +
                                    " photos (.jpg/.png); a reconstruction "
                                    "needs at least 3, overlapping");
  }
  // Every photo readable before anything is written.
  const bool in_capture_order = NamedInCaptureOrder(photos);
  const PhotoCameras cameras =
      GroupPhotosByCamera(DescribePhotos(photos), in_capture_order);
  fs::create_directories(ws / ".reconstruct");
  if (!fs::exists(images)) {
    fs::create_directory_symlink(photos_dir, images);
  } else if (!fs::equivalent(images, photos_dir)) {
    FailAt(images.string(), "exists and is not --image_path " +
                                photos_dir.string() +
                                ": use another workspace");
  }
  const int threads = o.num_threads > 0 ? o.num_threads : omp_get_num_procs();
  const bool gpu = cuda_colmap && fs::exists("/dev/nvidia0");
  const bool names_with_spaces =
      std::any_of(photos.begin(), photos.end(), [](const std::string& p) {
        return fs::path(p).filename().string().find(' ') != std::string::npos;
      });
  const ColmapPlan plan =
      PlanReconstruction(int(photos.size()), threads, gpu, cameras, o,
                         names_with_spaces, in_capture_order);
  std::vector<Stage> stages =
      ColmapStages(plan, o.colmap, ws, int64_t(photos.size()));

  // Stages done before must have run these settings: a resumed run does not
  // mix features or matches of two settings. Checked before any work.
  for (Stage& stage : stages) {
    stage.log_path = (ws / ".reconstruct" / (stage.name + ".log")).string();
  }
  std::vector<bool> done(stages.size(), false);
  for (size_t k = 0; k < stages.size(); ++k) {
    const fs::path marker = ws / ".reconstruct" / (stages[k].name + ".done");
    if (!fs::exists(marker)) continue;
    const std::vector<uint8_t> bytes = ReadFileBytes(marker.string());
    const std::string recorded(bytes.begin(), bytes.end());
    // A workspace matched by COLMAP's own matcher (before watergs matched
    // on the CPU) has its matches verified: that marker covers this stage
    // and the next.
    const std::string& former = stages[k].former_command;
    if (!former.empty() && k + 1 < stages.size() &&
        (recorded == StageMarker(former, ws) || recorded == former + "\n")) {
      done[k] = done[k + 1] = true;
      ++k;
      continue;
    }
    // Markers before the workspace-relative form held the command itself.
    if (recorded != StageMarker(stages[k].command, ws) &&
        recorded != stages[k].command + "\n") {
      FailAt(marker.string(), "was done with other settings: remove " +
                                  (ws / ".reconstruct").string() +
                                  " and the database to start over");
    }
    done[k] = true;
  }
  for (const std::string& reason : plan.reasons) {
    std::printf("reconstruct: %s\n", reason.c_str());
  }
  std::fflush(stdout);
  for (size_t k = 0; k < stages.size(); ++k) {
    const Stage& stage = stages[k];
    const fs::path marker = ws / ".reconstruct" / (stage.name + ".done");
    if (done[k]) {
      std::printf("reconstruct: %s done before, kept\n", stage.name.c_str());
      // Idempotent: a workspace whose mapping is not done gets its cameras
      // shared (again, or first when extracted before they were).
      if (stage.name == "features" && !done.back()) {
        ShareCamerasInDatabase(ws, photos, cameras);
      }
      continue;
    }
    if (stage.name == "mapping") {
      // A mapper stopped half way leaves partial models: start it afresh.
      fs::remove_all(ws / "sparse");
      fs::create_directories(ws / "sparse");
    }
    RunStage(stage);
    AtomicWriteFile(marker.string(), StageMarker(stage.command, ws));
    if (stage.name == "features") ShareCamerasInDatabase(ws, photos, cameras);
  }

  const std::string model = KeepLargestModel((ws / "sparse").string());
  const Reconstruction reconstruction = ReadReconstruction(model);
  const ModelSummary s = AnalyzeModel(reconstruction);
  std::printf(
      "reconstruct: %zu of %zu photos registered, %zu points, mean "
      "reprojection error %.2f px -> %s\n",
      s.num_reg_images, photos.size(), s.num_points3D,
      s.mean_reprojection_error, model.c_str());
  const double baseline = MedianNeighbourBaselineToDepth(reconstruction);
  if (baseline < kCollapsedBaselineToDepth) {
    std::printf(
        "reconstruct: warning: most photos sit at the pose of another "
        "(nearest camera %.2f%% of the scene's depth away, median; photos "
        "with parallax read 3-4%% on LLFF fern and horns, 29%% on the demo "
        "scene): photos registered onto one another (a "
        "symmetric scene), or taken from one spot (duplicates, a tripod, "
        "dense video frames). Check the poses with `watergs model_info "
        "--reference_path` where known ones exist\n",
        100 * baseline);
  }
  if (double(s.num_reg_images) < o.min_registered_fraction * photos.size()) {
    Fail("reconstruct: only " + std::to_string(s.num_reg_images) + " of " +
         std::to_string(photos.size()) +
         " photos registered: take photos with more overlap, or try "
         "--matcher exhaustive / more --max_features");
  }
}

std::string OutlierViewWarning(const std::string& train_report_json) {
  const nlohmann::json j =
      nlohmann::json::parse(train_report_json, nullptr, false);
  if (j.is_discarded() || !j.contains("views") || !j["views"].is_array()) {
    return "";
  }
  // Views with a PSNR (a NaN is written as null) and their names.
  std::vector<std::pair<std::string, double>> views;
  for (const auto& v : j["views"]) {
    if (!v.is_object() || !v.contains("psnr") || !v["psnr"].is_number()) {
      continue;
    }
    const bool named = v.contains("name") && v["name"].is_string();
    views.emplace_back(named ? v["name"].get<std::string>() : "?",
                       v["psnr"].get<double>());
  }
  double best = -1e300;
  for (const auto& [name, psnr] : views) best = std::max(best, psnr);
  std::string low;
  for (const auto& [name, psnr] : views) {
    if (psnr > best - kOutlierViewDb) continue;
    char item[160];
    std::snprintf(item, sizeof(item), "%s%s %.1f dB", low.empty() ? "" : ", ",
                  name.c_str(), psnr);
    low += item;
  }
  if (low.empty()) return "";
  char head[160];
  std::snprintf(head, sizeof(head),
                "pipeline: warning: held-out views %.0f dB or more below the "
                "best (%.1f dB): ",
                kOutlierViewDb, best);
  return head + low +
         ". Photos joined in a wrong pose read like this: if reconstruct "
         "matched sequentially, try --matcher exhaustive or more "
         "--max_features\n";
}

}  // namespace watergs
