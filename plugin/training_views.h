// Adapts a COLMAP Workspace to the trainer's TrainingViews source, and the
// helpers the train/render commands share (camera export, PNG output).
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "gaussian/image.h"
#include "gaussian/trainer.h"
#include "plugin/workspace.h"

namespace watergs {

// Views of a workspace; images come from the workspace's bounded cache.
class WorkspaceViews : public TrainingViews {
 public:
  explicit WorkspaceViews(const Workspace& workspace) : workspace_(workspace) {}
  size_t NumViews() const override { return workspace_.NumViews(); }
  std::string Name(size_t view) const override {
    return workspace_.ViewName(view);
  }
  RenderCamera Camera(size_t view) const override {
    return workspace_.ViewCamera(view);
  }
  std::shared_ptr<const ImageRGB> Image(size_t view) const override;
  bool HeldOut(size_t view) const override { return workspace_.HeldOut(view); }

 private:
  const Workspace& workspace_;
};

// Parses "r,g,b" (components in [0, 1]), "black" or "white"; throws Error.
std::array<float, 3> ParseBackground(const std::string& text);

// Writes Inria's cameras.json for `views` of `source`: a list of {id,
// img_name (name without extension), width, height, position (camera
// centre), rotation (camera-to-world, rows), fx, fy}, plus cx, cy (pixels,
// COLMAP convention), which Inria's file leaves out (a web viewer harness
// renders at exact intrinsics from it).
void WriteCamerasJson(const std::string& path, const TrainingViews& source,
                      const std::vector<size_t>& views);

// Writes an RGB image in [0, 1] as an 8-bit PNG, atomically.
void WritePng(const std::string& path, const ImageRGB& image);

// "dir/view_001.jpg" -> "view_001".
std::string NameStem(const std::string& name);

}  // namespace watergs
