// `watergs model_converter`: converts a COLMAP sparse model between the .bin
// and .txt formats, writing exactly what `colmap model_converter` writes.
#include <iostream>
#include <string>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/command.h"
#include "plugin/option_parser.h"
#include "plugin/reconstruction_io.h"

namespace {

int RunModelConverter(int argc, char** argv) {
  std::string input_path, output_path, output_type;
  watergs::OptionParser parser(
      "model_converter",
      "Converts a COLMAP sparse model to BIN or TXT (as colmap "
      "model_converter).");
  // colmap model_converter calls it --input_path; here --input_path is
  // always a 3DGS model (docs/cli.md, "Option names"), the old name an
  // alias.
  parser.AddRequired("sparse_path", &input_path,
                     "Sparse model folder, or a workspace holding sparse/0");
  parser.AddAlias("input_path", "sparse_path");
  parser.AddRequired("output_path", &output_path,
                     "Folder to write cameras/images/points3D into");
  parser.AddRequired("output_type", &output_type, "BIN or TXT");
  if (!parser.Parse(argc, argv)) return 0;
  const watergs::ModelFormat format = watergs::ParseModelFormat(output_type);
  // Converting in place would rewrite the input model (reordered) or leave
  // both formats side by side, the reader then taking the .bin ones.
  const std::string model_path = watergs::FindModelPath(input_path);
  if (watergs::SamePath(model_path, output_path)) {
    watergs::FailAt(output_path,
                    "holds the input model (--sparse_path " + input_path +
                        "): write the converted model to another folder");
  }
  const watergs::Reconstruction reconstruction =
      watergs::ReadReconstruction(model_path);
  watergs::WriteReconstruction(reconstruction, output_path, format);
  std::cout << "Wrote " << reconstruction.NumCameras() << " cameras, "
            << reconstruction.NumRegImages() << " images, "
            << reconstruction.NumPoints3D() << " points3D to " << output_path
            << "\n";
  return 0;
}

}  // namespace

WATERGS_COMMAND(model_converter, "Converts a COLMAP model between BIN and TXT",
                RunModelConverter);
