// Workspace adapter for training, cameras.json and PNG output.
#include "plugin/training_views.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "plugin/image_file.h"

namespace watergs {

std::shared_ptr<const ImageRGB> WorkspaceViews::Image(size_t view) const {
  return std::make_shared<const ImageRGB>(workspace_.LoadView(view));
}

std::array<float, 3> ParseBackground(const std::string& text) {
  if (text == "black") return {0.f, 0.f, 0.f};
  if (text == "white") return {1.f, 1.f, 1.f};
  const std::string usage = "--background: '" + text +
                            "' is not r,g,b (values in [0, 1]), black or white";
  std::vector<std::string> parts;
  std::istringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) parts.push_back(part);
  if (parts.size() != 3 || text.back() == ',') Fail(usage);
  std::array<float, 3> rgb{};
  for (int c = 0; c < 3; ++c) {
    try {
      size_t used = 0;
      rgb[c] = std::stof(parts[c], &used);
      if (used != parts[c].size()) Fail(usage);
    } catch (const std::logic_error&) {
      Fail(usage);
    }
    if (!(rgb[c] >= 0.f && rgb[c] <= 1.f)) Fail(usage);
  }
  return rgb;
}

std::string NameStem(const std::string& name) {
  const std::string file = std::filesystem::path(name).filename().string();
  // Inria: os.path.basename(path).split(".")[0].
  return file.substr(0, file.find('.'));
}

void WriteCamerasJson(const std::string& path, const TrainingViews& source,
                      const std::vector<size_t>& views) {
  nlohmann::json list = nlohmann::json::array();
  int id = 0;
  for (size_t view : views) {
    const RenderCamera cam = source.Camera(view);
    const Eigen::Vector3d center = cam.Center();
    const Eigen::Matrix3d rotation = cam.R.transpose();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) {
      rows.push_back({rotation(r, 0), rotation(r, 1), rotation(r, 2)});
    }
    list.push_back({{"id", id++},
                    {"img_name", NameStem(source.Name(view))},
                    {"width", cam.width},
                    {"height", cam.height},
                    {"position", {center.x(), center.y(), center.z()}},
                    {"rotation", rows},
                    {"fy", cam.fy},
                    {"fx", cam.fx},
                    {"cx", cam.cx},
                    {"cy", cam.cy}});
  }
  AtomicWriteFile(path, list.dump() + "\n");
}

void WritePng(const std::string& path, const ImageRGB& image) {
  WriteImageFile(path, image, ".png");
}

}  // namespace watergs
