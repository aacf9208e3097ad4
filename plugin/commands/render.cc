// `watergs render`: renders a 3DGS PLY from a workspace's cameras to PNGs
// and prints PSNR/SSIM against the workspace images.
#include <omp.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/rasterizer.h"
#include "gaussian/render_conventions.h"
#include "gaussian/trainer.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "plugin/command.h"
#include "plugin/image_file.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"

namespace {

using namespace watergs;

// Free viewpoints between the cameras (as extract --num_views samples them),
// each attacked in turn by `attacks` and written as free_NNN.png or, with a
// JPEG quality, .jpg: the copies a leak would hold.
void RenderFreeViews(const GaussianModel& model, const TrainingViews& views,
                     int num_views, uint64_t seed,
                     const std::vector<ImageAttackSpec>& attacks,
                     int jpeg_quality, const RenderOptions& options,
                     Rasterizer& rasterizer, const std::string& output_path) {
  const std::vector<RenderCamera> cameras =
      SampleFreeViewpoints(views, num_views, seed);
  ProgressBar bar("render", static_cast<int64_t>(cameras.size()));
  ImageRGB image;
  for (size_t k = 0; k < cameras.size(); ++k) {
    rasterizer.Forward(model, cameras[k], options, &image, nullptr);
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    for (const ImageAttackSpec& attack : attacks) {
      image = ApplyImageAttack(attack, image);
    }
    char name[32];
    std::snprintf(name, sizeof(name), "free_%03zu.%s", k,
                  jpeg_quality > 0 ? "jpg" : "png");
    WriteImageFile(output_path + "/" + name, image, "",
                   jpeg_quality > 0 ? jpeg_quality : 95);
    bar.Update(static_cast<int64_t>(k + 1));
  }
  bar.Finish();
  // The viewpoints as Inria's cameras.json (each render's camera before any
  // --image_attack): the ground truth a registration is checked against.
  InMemoryViews written;
  std::vector<size_t> all;
  for (size_t k = 0; k < cameras.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "free_%03zu", k);
    written.Add(name, cameras[k], ImageRGB());
    all.push_back(k);
  }
  WriteCamerasJson(output_path + "/cameras.json", written, all);
  std::printf("render: %zu free viewpoints (seed %llu) -> %s\n", cameras.size(),
              static_cast<unsigned long long>(seed), output_path.c_str());
}

int RunRender(int argc, char** argv) {
  int num_views = 0, jpeg_quality = 0;
  int64_t seed = 0;
  std::string image_attack;
  std::string input_path, output_path, split = "test", background = "0,0,0";
  WorkspaceOptions ws;
  int sh_degree = -1, num_threads = 0;
  OptionParser parser("render",
                      "Renders a 3DGS PLY from a COLMAP workspace's cameras "
                      "to PNGs and prints PSNR/SSIM against its images (when "
                      "the workspace has its image folder).");
  parser.AddRequired("input_path", &input_path,
                     "The model (PLY, compressed PLY, .spz, .splat or SOG)");
  parser.AddRequired("workspace_path", &ws.workspace_path,
                     "COLMAP workspace (images/ and sparse/0)");
  parser.Add("sparse_path", &ws.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("image_path", &ws.image_path,
             "Image folder (default <workspace>/images)");
  parser.AddRequired("output_path", &output_path,
                     "Folder for the PNGs and their cameras (cameras.json: "
                     "Inria's, with cx, cy)");
  parser.Add("split", &split,
             "Views to render: test (held out: test_views.txt, else every "
             "8th), train (the others) or all");
  parser.Add("downscale", &ws.downscale, "Image downscale: 1, 2, 4 or 8");
  parser.Add("background", &background, "r,g,b in [0, 1], black or white");
  parser.Add("sh_degree", &sh_degree, "SH degree to use (-1 = the model's)");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  parser.Add("num_views", &num_views,
             "Render N free viewpoints between the cameras instead (as "
             "extract --num_views samples them; no PSNR)");
  parser.Add("seed", &seed, "Seed of the free viewpoints");
  parser.Add("image_attack", &image_attack,
             "With --num_views: attacks applied to each render in turn, "
             "comma-separated: crop:F, resize:F, jpeg:Q");
  parser.Add("jpeg_quality", &jpeg_quality,
             "With --num_views: write JPEG files of this quality (1-100; 0 = "
             "PNG)");
  std::string align = "auto";
  parser.Add("align", &align, kAlignHelp);
  std::string conventions_name = "watergs";
  parser.Add(
      "render_conventions", &conventions_name,
      "Render as another renderer does (CPU only): " + RenderConventionsHelp());
  if (!parser.Parse(argc, argv)) return 0;
  const RenderConventions conventions =
      FindRenderConventions(conventions_name, "--render_conventions")
          .conventions;
  if (num_views < 0) Fail("--num_views must be >= 0");
  if (jpeg_quality < 0 || jpeg_quality > 100) {
    Fail("--jpeg_quality must be in 0..100 (0 = PNG)");
  }
  if (num_views == 0 && (!image_attack.empty() || jpeg_quality > 0)) {
    Fail("--image_attack and --jpeg_quality go with --num_views");
  }
  if (split != "test" && split != "train" && split != "all") {
    Fail("--split must be test, train or all, got '" + split + "'");
  }
  if (num_threads < 0) Fail("--num_threads must be >= 0");
  if (num_threads > 0) omp_set_num_threads(num_threads);
  const std::array<float, 3> bg = ParseBackground(background);
  const ModelData ply = ReadModelFile(input_path);
  if (sh_degree > ply.model.sh_degree || sh_degree < -1) {
    Fail("--sh_degree " + std::to_string(sh_degree) + " is not in -1.." +
         std::to_string(ply.model.sh_degree) + " for this model");
  }
  ws.images_optional = true;  // renders need only the cameras
  const Workspace workspace = Workspace::Open(ws);
  const bool truth = workspace.has_images();
  const WorkspaceViews workspace_views(workspace);
  auto rasterizer = MakeRasterizer(parser.device());
  const PlacedViews placed =
      PlaceByOption("render", align, *rasterizer, ply.model, input_path,
                    workspace, workspace_views, bg, /*suspect=*/true);
  const TrainingViews& views = placed.views();
  if (num_views > 0) {
    CreateDirectories(output_path);
    RenderOptions options;
    options.background = bg;
    options.active_sh_degree = sh_degree;
    options.conventions = conventions;
    RenderFreeViews(ply.model, views, num_views, uint64_t(seed),
                    image_attack.empty() ? std::vector<ImageAttackSpec>{}
                                         : ParseImageAttackList(image_attack),
                    jpeg_quality, options, *rasterizer, output_path);
    return 0;
  }
  std::vector<size_t> selected;
  if (split == "test") selected = workspace.TestViews(true);
  if (split == "train") selected = workspace.TrainViews(true);
  if (split == "all") selected = workspace.TrainViews(false);
  CreateDirectories(output_path);
  if (!truth) {
    std::printf("render: no image folder at %s: PNGs only, no PSNR/SSIM\n",
                workspace.options().image_path.c_str());
  }

  RenderOptions options;
  options.background = bg;
  options.active_sh_degree = sh_degree;
  options.conventions = conventions;
  ProgressBar bar("render", static_cast<int64_t>(selected.size()));
  nlohmann::json per_view = nlohmann::json::array();
  double psnr_sum = 0, ssim_sum = 0;
  ImageRGB image;
  for (size_t k = 0; k < selected.size(); ++k) {
    const size_t view = selected[k];
    rasterizer->Forward(ply.model, views.Camera(view), options, &image,
                        nullptr);
    for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
    const std::string name = NameStem(views.Name(view));
    WritePng(output_path + "/" + name + ".png", image);
    if (truth) {
      const auto truth_image = views.Image(view);
      const double psnr = Psnr(image, *truth_image);
      const double ssim = Ssim(image, *truth_image);
      psnr_sum += psnr;
      ssim_sum += ssim;
      per_view.push_back(
          {{"name", views.Name(view)}, {"psnr", psnr}, {"ssim", ssim}});
      std::printf("%-24s PSNR %6.2f dB  SSIM %.4f\n", views.Name(view).c_str(),
                  psnr, ssim);
    } else {
      per_view.push_back({{"name", views.Name(view)}});
    }
    bar.Update(static_cast<int64_t>(k + 1));
  }
  bar.Finish();
  // The rendered cameras as Inria's cameras.json (with cx, cy), as for free
  // viewpoints: another renderer can be compared at exactly these cameras.
  WriteCamerasJson(output_path + "/cameras.json", views, selected);
  const double n = std::max<size_t>(selected.size(), 1);
  nlohmann::json report = {
      {"model", input_path},
      {"split", split},
      {"num_views", selected.size()},
      {"psnr", truth ? nlohmann::json(psnr_sum / n) : nlohmann::json()},
      {"ssim", truth ? nlohmann::json(ssim_sum / n) : nlohmann::json()},
      {"views", per_view}};
  report["provenance"] = Provenance(argc, argv);
  AtomicWriteFile(output_path + "/render_report.json", report.dump(2) + "\n");
  // "all 9 views", "1 test view", "7 train views".
  const size_t count = selected.size();
  const std::string views_text =
      (split == "all" ? "all " + std::to_string(count)
                      : std::to_string(count) + " " + split) +
      (count == 1 ? " view" : " views");
  if (truth) {
    std::printf("render: %s, mean PSNR %.2f dB, SSIM %.4f -> %s\n",
                views_text.c_str(), psnr_sum / n, ssim_sum / n,
                output_path.c_str());
  } else {
    std::printf("render: %s -> %s\n", views_text.c_str(), output_path.c_str());
  }
  return 0;
}

}  // namespace

WATERGS_COMMAND(render, "Renders a 3DGS PLY from workspace cameras to PNGs",
                RunRender);
