// `watergs transforms_importer`: a NeRF-synthetic, nerfstudio or Instant-NGP
// transforms.json scene written as a COLMAP workspace the other commands
// read (plugin/transforms_import.h).
#include <cstdio>
#include <iostream>
#include <string>

#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "plugin/training_views.h"
#include "plugin/transforms_import.h"

namespace {

int RunTransformsImporter(int argc, char** argv) {
  watergs::TransformsImportOptions options;
  std::string background = "white";
  watergs::OptionParser parser(
      "transforms_importer",
      "Writes a transforms.json scene (NeRF-synthetic's "
      "transforms_{train,test}.json, nerfstudio, Instant-NGP) as a COLMAP "
      "workspace: images/ (RGBA composited on --background), sparse/0 with "
      "random initial points, and test_views.txt holding the scene's test "
      "split out (train and embed --split train, eval --split test use it).");
  parser.AddRequired("transforms_path", &options.transforms_path,
                     "transforms.json, or the folder holding it or "
                     "transforms_train.json (+ transforms_test.json)");
  parser.AddRequired("output_path", &options.output_path,
                     "workspace folder to create (new or empty)");
  parser.Add("background", &background,
             "r,g,b, black or white: what RGBA images are composited on "
             "(NeRF-synthetic is read on white by GuardSplat, 3D-GSW and the "
             "NeRF papers); train/embed/eval then take the same --background");
  parser.Add("num_points", &options.num_points,
             "random initial points (the scenes have no SfM points; Inria "
             "starts NeRF-synthetic from 100,000)");
  parser.Add("points_half_side", &options.points_half_side,
             "half side of the points' cube, times the median camera "
             "distance to the point the cameras look at");
  parser.Add("test_stride", &options.test_stride,
             "keep every k-th test frame (NeRF-synthetic has 200)");
  parser.Add("seed", &options.seed, "random seed of the initial points");
  if (!parser.Parse(argc, argv)) return 0;
  options.background = watergs::ParseBackground(background);
  const watergs::TransformsImportSummary summary =
      watergs::ImportTransforms(options);
  char centre[128];
  std::snprintf(centre, sizeof centre, "(%.3g, %.3g, %.3g), half side %.3g",
                summary.centre.x(), summary.centre.y(), summary.centre.z(),
                summary.half_side);
  std::cout << "Wrote " << options.output_path << ": " << summary.train_views
            << " training and " << summary.test_views << " test views ("
            << summary.composited << " composited on the background), "
            << summary.cameras << " camera(s), " << summary.points
            << " random points in a cube at " << centre << "\n"
            << "Next: watergs train --workspace_path " << options.output_path
            << " --output_path OUT --split train"
            << (background == "black" || background == "0,0,0"
                    ? std::string()
                    : " --background " + background)
            << "\n";
  return 0;
}

}  // namespace

WATERGS_COMMAND(transforms_importer,
                "Writes a transforms.json scene (NeRF-synthetic, nerfstudio, "
                "Instant-NGP) as a COLMAP workspace",
                RunTransformsImporter);
