// `watergs train`: trains a 3DGS model on a COLMAP workspace (Inria's recipe)
// and writes point_cloud.ply, cameras.json, train_log.jsonl and report.json.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/point_init.h"
#include "gaussian/trainer.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "gaussian/util/text_util.h"
#include "plugin/command.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"

namespace {

using namespace watergs;

// "7000,30000" or "7000 30000" -> iterations; throws Error.
std::vector<int64_t> ParseIterationList(const std::string& text) {
  std::vector<int64_t> out;
  std::string token;
  std::istringstream in(text);
  while (in >> token) {
    for (const std::string& part : SplitList(token)) {
      try {
        size_t used = 0;
        out.push_back(std::stoll(part, &used));
        if (used != part.size() || out.back() < 1) throw std::out_of_range("");
      } catch (const std::logic_error&) {
        Fail("--test_iterations: '" + part + "' is not a positive iteration");
      }
    }
  }
  return out;
}

struct TrainArgs {
  WorkspaceOptions workspace;
  std::string output_path;
  int64_t iterations = 30000;
  int sh_degree = 3;
  std::string background = "0,0,0";
  int64_t seed = 0;
  int num_threads = 0;
  // Where the rasterizer ran ("cpu" or "cuda"), for the report.
  std::string device = "cpu";
  // --split: all, or train (every 8th view held out, so that eval scores
  // unseen views); eval: split == "train".
  std::string split = "all";
  bool eval = false;
  int64_t checkpoint_every = 0;
  bool resume = false;
  std::string test_iterations = "7000,30000";
  int64_t log_every = 10;
  int64_t densify_from_iter = 500;
  int64_t densify_until_iter = 15000;
  double densify_grad_threshold = 0.0002;
  bool compact_optimizer = false;
  std::string moment_precision = "float32";
  bool overwrite = false;
  // 0: --iterations.
  int64_t position_lr_max_steps = 0;
  // "": start from the SfM points.
  std::string init_path;
};

void Validate(const TrainArgs& a) {
  if (a.iterations < 1) Fail("--iterations must be at least 1");
  if (a.moment_precision != "float32" && a.moment_precision != "bfloat16") {
    Fail("--moment_precision must be float32 or bfloat16, not '" +
         Printable(a.moment_precision) + "'");
  }
  if (a.sh_degree < 0 || a.sh_degree > 3) Fail("--sh_degree must be 0-3");
  const int d = a.workspace.downscale;
  if (d != 1 && d != 2 && d != 4 && d != 8) {
    Fail("--downscale must be 1, 2, 4 or 8");
  }
  if (a.num_threads < 0) Fail("--num_threads must be >= 0 (0 = all cores)");
  if (a.checkpoint_every < 0) Fail("--checkpoint_every must be >= 0");
  if (a.log_every < 1) Fail("--log_every must be >= 1");
  if (!(a.densify_grad_threshold > 0) ||
      !std::isfinite(a.densify_grad_threshold)) {
    Fail("--densify_grad_threshold must be a positive number");
  }
  if (a.position_lr_max_steps < 0) {
    Fail("--position_lr_max_steps must be >= 0 (0 = --iterations)");
  }
}

// The files a run writes into its output folder.
const char* const kRunFiles[] = {"point_cloud.ply", "report.json",
                                 "cameras.json", "train_log.jsonl",
                                 "checkpoint.ckpt"};

// Refuses an output folder that is the workspace, or is or lies inside its
// image or model folder (a run's files would mix with, or be read as, its
// inputs), and one holding an earlier run unless it is resumed or replaced.
// Runs before anything is written.
void CheckOutputFolder(const TrainArgs& a, const Workspace& workspace) {
  namespace fs = std::filesystem;
  const std::string& out = a.output_path;
  struct Input {
    const char* what;
    std::string path;
    // Whether a folder inside it is refused too (the workspace may hold
    // outputs beside images/ and sparse/).
    bool nor_inside;
  };
  const Input inputs[] = {
      {"the workspace", a.workspace.workspace_path, false},
      {"the image folder", workspace.options().image_path, true},
      {"the sparse model folder", workspace.model_path(), true}};
  for (const Input& input : inputs) {
    if (input.path.empty()) continue;
    if (SamePath(out, input.path)) {
      FailAt(out, std::string("is ") + input.what +
                      ": choose an output folder that holds no inputs");
    }
    std::error_code ec;
    for (fs::path p = fs::weakly_canonical(out, ec).parent_path();
         !ec && input.nor_inside && p.has_relative_path();
         p = p.parent_path()) {
      if (SamePath(p.string(), input.path)) {
        FailAt(out, std::string("lies inside ") + input.what + " (" +
                        input.path +
                        "): choose an output folder that holds no inputs");
      }
    }
  }
  if (a.resume || a.overwrite) return;
  for (const char* name : kRunFiles) {
    const std::string file = out + "/" + name;
    if (!fs::exists(file)) continue;
    FailAt(out, std::string("holds an earlier run (") + name +
                    "): --resume continues it, --overwrite replaces it");
  }
}

// The model --init_path names, in the workspace's frame: read in any format,
// its SH degree checked against --sh_degree, and, when it does not match the
// photos as given, aligned as embed's --align auto does (then moved onto the
// workspace, since training happens in the workspace's frame). Throws Error.
GaussianModel ReadInitialModel(const TrainArgs& a, const Workspace& workspace,
                               const TrainingViews& views,
                               const std::array<float, 3>& background,
                               Rasterizer& rasterizer) {
  GaussianModel model = ReadModelFile(a.init_path).model;
  if (model.size() == 0) FailAt(a.init_path, "holds no Gaussians");
  if (model.sh_degree != a.sh_degree) {
    FailAt(a.init_path, "has SH degree " + std::to_string(model.sh_degree) +
                            ", --sh_degree is " + std::to_string(a.sh_degree) +
                            ": pass --sh_degree " +
                            std::to_string(model.sh_degree));
  }
  const PlacedViews placed =
      PlaceByOption("train", "auto", rasterizer, model, a.init_path, workspace,
                    views, background);
  if (placed.placement.moved) {
    ApplySimilarity(Inverse(placed.placement.workspace_to_model), &model);
  }
  return model;
}

void WriteReport(const std::string& path, const TrainArgs& a,
                 const Trainer& trainer, const EvalResult& eval,
                 const std::string& split, const std::vector<size_t>& views,
                 const TrainingViews& source, double extent,
                 const nlohmann::json& provenance) {
  nlohmann::json j;
  j["iterations"] = trainer.iteration();
  j["num_gaussians"] = trainer.model().size();
  j["train_seconds"] = trainer.elapsed_seconds();
  j["iterations_per_second"] =
      trainer.elapsed_seconds() > 0
          ? trainer.iteration() / trainer.elapsed_seconds()
          : 0.0;
  j["scene_extent"] = extent;
  j["seed"] = a.seed;
  if (!a.init_path.empty()) j["init_path"] = a.init_path;
  j["num_threads"] = omp_get_max_threads();
  j["device"] = a.device;
  j["sh_degree"] = a.sh_degree;
  j["eval"] = a.eval;
  j["compact_optimizer"] = a.compact_optimizer;
  j["moment_precision"] = a.compact_optimizer ? "compact8" : a.moment_precision;
  j["state_bytes_per_gaussian"] = trainer.StateBytesPerGaussian();
  j["metrics_split"] = split;
  j["num_metric_views"] = eval.num_views;
  j["psnr"] = eval.psnr;
  j["ssim"] = eval.ssim;
  j["l1"] = eval.l1;
  nlohmann::json per_view = nlohmann::json::array();
  for (size_t k = 0; k < views.size(); ++k) {
    per_view.push_back({{"name", source.Name(views[k])},
                        {"psnr", eval.view_psnr[k]},
                        {"ssim", eval.view_ssim[k]}});
  }
  j["views"] = per_view;
  j["provenance"] = provenance;
  AtomicWriteFile(path, j.dump(2) + "\n");
}

int RunTrain(int argc, char** argv) {
  TrainArgs a;
  OptionParser parser("train",
                      "Trains a 3D Gaussian Splatting model on a COLMAP "
                      "workspace (Inria's 3DGS recipe).");
  parser.AddRequired("workspace_path", &a.workspace.workspace_path,
                     "COLMAP workspace (images/ and sparse/0)");
  parser.Add("sparse_path", &a.workspace.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.AddAlias("input_path", "sparse_path");
  parser.Add("image_path", &a.workspace.image_path,
             "Image folder (default <workspace>/images)");
  parser.AddRequired("output_path", &a.output_path,
                     "Output folder (created when training starts); one "
                     "holding an earlier run needs --resume or --overwrite");
  parser.AddFlag("overwrite", &a.overwrite,
                 "Replace the earlier run in --output_path (its checkpoint "
                 "is deleted when training starts)");
  parser.Add("iterations", &a.iterations,
             "Training iterations. The position learning rate decays over "
             "--position_lr_max_steps, by default this many, so runs of "
             "different lengths differ from the first iteration on; with "
             "--position_lr_max_steps fixed, a shorter run is the start of "
             "a longer one (up to its last iteration, which takes no step)");
  parser.Add("position_lr_max_steps", &a.position_lr_max_steps,
             "Iterations over which the position learning rate decays from "
             "1.6e-4 to 1.6e-6 (times the scene extent); 0 = --iterations "
             "(Inria's default is a fixed 30000)");
  parser.Add("downscale", &a.workspace.downscale,
             "Image downscale factor: 1, 2, 4 or 8");
  parser.Add("init_path", &a.init_path,
             "Start from this model (any format watergs reads) instead of "
             "the SfM points, at its own SH degree (which must be "
             "--sh_degree): for example a model trained at --downscale 4, "
             "refined and densified at full size, or a splat from another "
             "trainer. One that does not match the photos is aligned as "
             "embed's --align auto does, then trained in the workspace's "
             "frame");
  parser.Add("sh_degree", &a.sh_degree, "Highest SH degree (0-3)");
  parser.Add("background", &a.background,
             "Background colour: r,g,b in [0, 1], black or white");
  parser.Add("seed", &a.seed, "Random seed (view order, splits)");
  parser.Add("num_threads", &a.num_threads,
             "Threads (0 = all cores); results are reproducible for a given "
             "seed and thread count");
  parser.Add("split", &a.split,
             "Views to train on: all, or train (all but the held-out views, "
             "whose PSNR is logged: the workspace's test_views.txt, else "
             "every 8th, LLFF's and Mip-NeRF 360's hold-out; Inria's --eval)");
  parser.AddAlias("eval", "split", "train");
  parser.Add("checkpoint_every", &a.checkpoint_every,
             "Write OUT/checkpoint.ckpt every N iterations (0 = never)");
  parser.AddFlag("resume", &a.resume,
                 "Continue from OUT/checkpoint.ckpt (same options)");
  parser.Add("test_iterations", &a.test_iterations,
             "Iterations at which held-out PSNR is logged (with --split "
             "train)");
  parser.Add("log_every", &a.log_every, "Write a log line every N iterations");
  parser.Add("densify_from_iter", &a.densify_from_iter,
             "First iteration of adaptive density control (Inria: 500)");
  parser.Add("densify_until_iter", &a.densify_until_iter,
             "Last iteration of adaptive density control (Inria: 15000)");
  parser.Add("densify_grad_threshold", &a.densify_grad_threshold,
             "Mean screen-space position gradient above which a Gaussian is "
             "cloned or split (Inria: 0.0002; lower grows more Gaussians)");
  parser.AddFlag("compact_optimizer", &a.compact_optimizer,
                 "Compact Adam moments (83 instead of 472 bytes per "
                 "Gaussian; not Inria's exact optimiser; overrides "
                 "--moment_precision)");
  parser.Add(
      "moment_precision", &a.moment_precision,
      "Adam moments of all groups but positions: float32 (Inria's; "
      "795 bytes of training state per Gaussian at SH degree 3) or "
      "bfloat16 with stochastic rounding (571 bytes; see docs/benchmarks.md "
      "for its quality)");
  if (!parser.Parse(argc, argv)) return 0;
  if (a.split != "all" && a.split != "train") {
    Fail("train: --split all or train, not '" + a.split + "'");
  }
  a.eval = a.split == "train";
  a.device = DeviceName(parser.device());
  Validate(a);
  if (a.num_threads > 0) omp_set_num_threads(a.num_threads);
  const std::array<float, 3> background = ParseBackground(a.background);
  const std::vector<int64_t> test_iterations =
      ParseIterationList(a.test_iterations);

  const std::string out = a.output_path;
  const std::string checkpoint_path = out + "/checkpoint.ckpt";
  if (a.resume && a.overwrite) Fail("train: --resume or --overwrite, not both");
  if (a.resume && !std::filesystem::exists(checkpoint_path)) {
    FailAt(checkpoint_path,
           "no checkpoint to resume (train with --checkpoint_every N)");
  }
  const Workspace workspace = Workspace::Open(a.workspace);
  CheckOutputFolder(a, workspace);
  const WorkspaceViews views(workspace);
  const std::vector<size_t> train_views = workspace.TrainViews(a.eval);
  const std::vector<size_t> test_views = workspace.TestViews(a.eval);
  std::unique_ptr<Rasterizer> rasterizer = MakeRasterizer(parser.device());
  GaussianModel init;
  if (a.init_path.empty()) {
    std::vector<float> xyz, rgb;
    workspace.PointCloud(&xyz, &rgb);
    if (xyz.empty()) {
      FailAt(workspace.model_path(), "has no 3D points to initialise from");
    }
    init = InitGaussiansFromPoints(xyz, rgb, a.sh_degree);
  } else {
    init = ReadInitialModel(a, workspace, views, background, *rasterizer);
  }
  const double extent = workspace.SceneExtent();
  const RenderCamera first = views.Camera(train_views.front());
  std::printf(
      "train: %zu training views, %zu held out, %dx%d, %zu %s, "
      "scene extent %.3f, %d threads, device %s\n",
      train_views.size(), test_views.size(), first.width, first.height,
      init.size(),
      a.init_path.empty() ? "SfM points" : "Gaussians from --init_path", extent,
      omp_get_max_threads(), DeviceName(parser.device()).c_str());

  TrainerOptions options;
  options.iterations = a.iterations;
  options.background = background;
  options.seed = static_cast<uint64_t>(a.seed);
  options.adam.position_lr_max_steps =
      a.position_lr_max_steps > 0 ? a.position_lr_max_steps : a.iterations;
  options.adam.compact_moments = a.compact_optimizer;
  // The 8-bit compact moments replace either precision.
  options.adam.half_moments =
      !a.compact_optimizer && a.moment_precision == "bfloat16";
  options.density.densify_from_iter = a.densify_from_iter;
  options.density.densify_until_iter = a.densify_until_iter;
  options.density.grad_threshold = a.densify_grad_threshold;
  options.density.white_background =
      background == std::array<float, 3>{1, 1, 1};
  options.checkpoint_path = checkpoint_path;
  options.checkpoint_every = a.checkpoint_every;
  options.log_path = out + "/train_log.jsonl";
  options.log_every = a.log_every;
  options.test_views = test_views;
  options.test_iterations = test_iterations;
  options.show_progress = true;
  // A trained model's higher SH bands already mean something.
  if (!a.init_path.empty()) options.initial_sh_degree = init.sh_degree;
  Trainer trainer(options, views, train_views, std::move(init), extent,
                  std::move(rasterizer));
  if (a.resume) {
    trainer.Resume(checkpoint_path);
    std::printf("train: resumed at iteration %lld\n",
                static_cast<long long>(trainer.iteration()));
  }
  // The folder appears only now that every input has been read, and goes
  // again if the run fails before writing into it.
  const bool created = !std::filesystem::exists(out);
  CreateDirectories(out);
  try {
    // The replaced run's checkpoint must not be resumed later.
    std::error_code ec;
    if (a.overwrite) std::filesystem::remove(checkpoint_path, ec);
    trainer.Run();
  } catch (...) {
    std::error_code ec;
    if (created && std::filesystem::is_empty(out, ec)) {
      std::filesystem::remove(out, ec);
    }
    throw;
  }

  WritePly(out + "/point_cloud.ply", trainer.model());
  std::vector<size_t> all_views = test_views;
  all_views.insert(all_views.end(), train_views.begin(), train_views.end());
  WriteCamerasJson(out + "/cameras.json", views, all_views);
  const bool held_out = !test_views.empty();
  const std::vector<size_t>& metric_views = held_out ? test_views : train_views;
  const EvalResult eval =
      EvaluateViews(trainer.rasterizer(), trainer.model(), views, metric_views,
                    background, trainer.active_sh_degree());
  const std::string split = held_out ? "test" : "train";
  WriteReport(out + "/report.json", a, trainer, eval, split, metric_views,
              views, extent, Provenance(argc, argv));

  std::printf("train: %lld iterations in %s (%.1f it/s), %zu Gaussians\n",
              static_cast<long long>(trainer.iteration()),
              FormatDuration(trainer.elapsed_seconds()).c_str(),
              trainer.elapsed_seconds() > 0
                  ? trainer.iteration() / trainer.elapsed_seconds()
                  : 0.0,
              trainer.model().size());
  std::printf("train: %s views (%zu): PSNR %.2f dB  SSIM %.4f  L1 %.4f\n",
              held_out ? "held-out" : "training (no --split train)",
              eval.num_views, eval.psnr, eval.ssim, eval.l1);
  std::printf(
      "train: wrote %s/{point_cloud.ply, cameras.json, train_log.jsonl, "
      "report.json}\n",
      out.c_str());
  return 0;
}

}  // namespace

WATERGS_COMMAND(train, "Trains a 3DGS model on a COLMAP workspace", RunTrain);
