// Test helpers shared by the CLI tests: a COLMAP workspace whose images are
// renders of Gaussians placed at its SfM points, so that training and
// embedding on it converge quickly; a tiny decoder; a PLY in a non-default
// layout.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "gaussian/formats/ply_io.h"
#include "gaussian/gaussian_model.h"
#include "gaussian/image.h"
#include "gaussian/point_init.h"
#include "gaussian/rasterizer.h"
#include "gaussian/util/file_util.h"
#include "plugin/reconstruction_io.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/hidden_model.h"

namespace watergs::testing {

// Writes ws/sparse/0 (text) of `options` and ws/images rendered from opaque
// Gaussians at the SfM points; returns ws. `truth` (if given) gets them.
inline std::string MakeRenderedWorkspace(const std::string& ws,
                                         const SyntheticModelOptions& options,
                                         GaussianModel* truth = nullptr) {
  const Reconstruction model = MakeSyntheticReconstruction(options);
  WriteReconstruction(model, ws + "/sparse/0", ModelFormat::kText);
  CreateDirectories(ws + "/images");
  // Blank placeholders first: the Workspace checks image sizes on open, and
  // the renders go through the same Workspace code the CLI uses.
  for (const auto& [id, image] : model.Images()) {
    WritePng(ws + "/images/" + image.name,
             ImageRGB(options.width, options.height));
  }
  WorkspaceOptions wo;
  wo.workspace_path = ws;
  const Workspace workspace = Workspace::Open(wo);
  std::vector<float> xyz, rgb;
  workspace.PointCloud(&xyz, &rgb);
  GaussianModel gaussians = InitGaussiansFromPoints(xyz, rgb, 1);
  for (float& logit : gaussians.opacity_logits) logit = 2.f;
  auto rasterizer = MakeCpuRasterizer();
  for (size_t v = 0; v < workspace.NumViews(); ++v) {
    ImageRGB image;
    rasterizer->Forward(gaussians, workspace.ViewCamera(v), RenderOptions{},
                        &image, nullptr);
    WritePng(ws + "/images/" + workspace.ViewName(v), image);
  }
  if (truth) *truth = std::move(gaussians);
  return ws;
}

// The small scene the embedding CLI tests render: 6 pinhole views of 48x36,
// 150 SfM points.
inline SyntheticModelOptions SmallSceneOptions() {
  SyntheticModelOptions options;
  options.num_images = 6;
  options.num_points = 150;
  options.width = 48;
  options.height = 36;
  return options;
}

// A one-line error naming `what`, non-zero exit.
inline void ExpectOneLineError(const CommandResult& run,
                               const std::string& what) {
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find(what), std::string::npos) << run.output;
  EXPECT_LE(std::count(run.output.begin(), run.output.end(), '\n'), 1)
      << run.output;
}

// Writes an untrained 16-bit decoder (6 channels, 2 blocks, no encoder) to
// `path`: small enough for CLI tests; returns path.
inline std::string WriteTinyDecoder(const std::string& path) {
  HiddenConfig config;
  config.num_bits = 16;
  config.channels = 6;
  config.encoder_blocks = 1;
  config.decoder_blocks = 2;
  HiddenModel net(config, false, 3);
  SaveHiddenModel(path, net, false);
  return path;
}

// Writes `model` as an ASCII PLY with non-zero normals (a layout other than
// the writer's default, which outputs must keep); returns path.
inline std::string WriteAsciiPlyWithNormals(const std::string& path,
                                            const GaussianModel& model) {
  PlyLayout layout = InriaPlyLayout(1, model.size());
  layout.format = PlyFormat::kAscii;
  for (size_t k = 0; k < layout.extra_values.size(); ++k) {
    layout.extra_values[k] = 0.25 * double(k % 7);
  }
  WritePly(path, model, layout);
  return path;
}

}  // namespace watergs::testing
