// `watergs reconstruct`: a folder of photos -> a COLMAP workspace that
// `train` reads, with COLMAP's binary (plugin/colmap_workflow.h).
#include <cstdio>
#include <string>

#include "gaussian/util/error.h"
#include "plugin/colmap_workflow.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"

namespace watergs {
namespace {

int RunReconstruct(int argc, char** argv) {
  ReconstructOptions o;
  OptionParser parser(
      "reconstruct",
      "Runs COLMAP's feature extraction, matching and mapping on a folder of "
      "photos, with settings chosen for the photo count and the machine, and "
      "writes the workspace every watergs command reads (images/, "
      "sparse/0: the largest model, database.db). Resumes from the first "
      "stage not finished.");
  parser.Add("image_path", &o.image_path,
             "Folder of photos (.jpg/.png; default <workspace>/images)");
  parser.AddRequired("workspace_path", &o.workspace_path,
                     "Workspace to write (created; images/ links the photos)");
  parser.Add("colmap", &o.colmap, "COLMAP binary");
  parser.Add("max_features", &o.max_features,
             "SIFT features an image (0: 2,048 on the CPU, 8,192 with GPU "
             "SIFT)");
  parser.Add("matcher", &o.matcher,
             "auto (photos named in capture order: exhaustive up to "
             "--sequential_above photos, sequential beyond; photos in no "
             "order: exhaustive), exhaustive or sequential");
  parser.Add("sequential_above", &o.sequential_above,
             "Photos named in capture order are matched sequentially above "
             "this many");
  parser.Add("num_threads", &o.num_threads, "Threads (0 = all cores)");
  parser.Add("min_registered", &o.min_registered_fraction,
             "Fewest photos the model must register, as a fraction");
  if (!parser.Parse(argc, argv)) return 0;
  if (o.matcher != "auto" && o.matcher != "exhaustive" &&
      o.matcher != "sequential") {
    Fail("reconstruct: --matcher must be auto, exhaustive or sequential");
  }
  if (o.sequential_above < 2) {
    Fail("reconstruct: --sequential_above must be >= 2");
  }
  if (o.max_features < 0 || o.num_threads < 0) {
    Fail("reconstruct: --max_features and --num_threads must be >= 0");
  }
  if (!(o.min_registered_fraction >= 0 && o.min_registered_fraction <= 1)) {
    Fail("reconstruct: --min_registered must be in [0, 1]");
  }
  RunReconstruction(o);
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(reconstruct,
                "Reconstructs a COLMAP workspace from a folder of photos",
                watergs::RunReconstruct);
