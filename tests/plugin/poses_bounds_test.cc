// LLFF poses_bounds.npy read as a reconstruction: a file written here from a
// synthetic model's poses in LLFF's convention (camera-to-world columns
// down, right, backwards) reads back as the same poses (ComparePoses finds
// scale 1 and no error), through model_info too; malformed files get one
// line naming the file.
#include "plugin/poses_bounds.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "gaussian/util/error.h"
#include "plugin/pose_comparison.h"
#include "plugin/reconstruction_io.h"
#include "tests/plugin/synthetic_model.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// A version-1 .npy of `rows` x `columns` little-endian values of `descr`.
void WriteNpy(const std::string& path, const std::vector<double>& values,
              size_t rows, size_t columns, const std::string& descr = "<f8") {
  std::string header =
      "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" +
      std::to_string(rows) + ", " + std::to_string(columns) + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string bytes = "\x93NUMPY";
  bytes += char(1);
  bytes += char(0);
  const uint16_t length = uint16_t(header.size());
  bytes.append(reinterpret_cast<const char*>(&length), 2);
  bytes += header;
  bytes.append(reinterpret_cast<const char*>(values.data()),
               values.size() * sizeof(double));
  std::ofstream(path, std::ios::binary) << bytes;
}

// The model's images by name, as LLFF rows: [down right back centre hwf]
// row by row, then near and far.
std::vector<double> LlffRows(const Reconstruction& model,
                             std::vector<std::string>* names) {
  std::vector<image_t> ids = model.RegImageIds();
  std::sort(ids.begin(), ids.end(), [&](image_t a, image_t b) {
    return model.GetImage(a).name < model.GetImage(b).name;
  });
  std::vector<double> rows;
  for (const image_t id : ids) {
    const Image& image = model.GetImage(id);
    const Camera& camera = model.GetCamera(image.camera_id);
    const Eigen::Matrix3d c2w = image.RotationMatrix().transpose();
    const Eigen::Vector3d centre = image.ProjectionCenter();
    const double hwf[3] = {double(camera.height), double(camera.width),
                           camera.params[0]};
    for (int r = 0; r < 3; ++r) {
      rows.insert(rows.end(),
                  {c2w(r, 1), c2w(r, 0), -c2w(r, 2), centre(r), hwf[r]});
    }
    rows.insert(rows.end(), {0.5, 20.0});
    names->push_back(image.name);
  }
  return rows;
}

TEST(PosesBounds, ReadsLlffPosesAsTheModelsOwn) {
  testing::TempDir dir("poses_bounds");
  testing::SyntheticModelOptions options;
  options.num_images = 9;
  const Reconstruction model = testing::MakeSyntheticReconstruction(options);
  std::vector<std::string> names;
  const std::vector<double> rows = LlffRows(model, &names);
  const std::string npy = dir / "poses_bounds.npy";
  WriteNpy(npy, rows, names.size(), 17);
  fs::create_directories(dir / "images");
  for (const std::string& name : names) {
    std::ofstream(dir / ("images/" + name)) << "x";
  }
  std::ofstream(dir / "images/notes.txt") << "not a photo";
  EXPECT_EQ(PosesBoundsImageNames(npy), names);
  const Reconstruction reference = ReadPosesBounds(npy, names);
  ASSERT_EQ(reference.NumRegImages(), names.size());
  const PoseComparison c = ComparePoses(model, reference);
  EXPECT_EQ(c.num_common, names.size());
  EXPECT_NEAR(c.scale, 1.0, 1e-9);
  EXPECT_LT(c.max_center_error, 1e-9);
  EXPECT_LT(c.max_rotation_error_deg, 1e-6);
  // A swapped axis pair is caught: right and down exchanged back.
  std::vector<double> swapped = rows;
  for (size_t i = 0; i < names.size(); ++i) {
    for (int r = 0; r < 3; ++r) {
      std::swap(swapped[17 * i + 5 * r], swapped[17 * i + 5 * r + 1]);
    }
  }
  WriteNpy(dir / "swapped.npy", swapped, names.size(), 17);
  EXPECT_THROW(ReadPosesBounds(dir / "swapped.npy", names), Error)
      << "a reflection is not a rotation";
  // model_info compares a workspace with it.
  WriteReconstruction(model, dir / "sparse/0", ModelFormat::kBinary);
  const testing::CommandResult cli =
      testing::RunCommand(testing::WatergsBin() + " model_info --sparse_path " +
                          dir.path() + " --reference_path " + npy);
  EXPECT_EQ(cli.exit_code, 0) << cli.output;
  EXPECT_NE(cli.output.find("9 common images"), std::string::npos)
      << cli.output;
}

TEST(PosesBounds, MalformedFilesGetOneLineNamingTheFile) {
  testing::TempDir dir("poses_bounds_bad");
  const std::vector<double> row(17, 1.0);
  auto expect_error = [&](const std::string& path,
                          const std::vector<std::string>& names,
                          const std::string& problem) {
    try {
      ReadPosesBounds(path, names);
      ADD_FAILURE() << "accepted: " << path;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(problem), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  };
  WriteNpy(dir / "count.npy", row, 1, 17);
  expect_error(dir / "count.npy", {"a.jpg", "b.jpg"}, "has 1 poses for 2");
  WriteNpy(dir / "f4.npy", row, 1, 17, "<f4");
  expect_error(dir / "f4.npy", {"a.jpg"}, "not float64");
  WriteNpy(dir / "shape.npy", row, 1, 16);
  expect_error(dir / "shape.npy", {"a.jpg"}, "not (N, 17)");
  std::ofstream(dir / "garbage.npy") << "garbage";
  expect_error(dir / "garbage.npy", {"a.jpg"}, "not a .npy file");
  std::vector<double> nan_row(17, 0.0);
  nan_row[3] = std::nan("");
  WriteNpy(dir / "nan.npy", nan_row, 1, 17);
  expect_error(dir / "nan.npy", {"a.jpg"}, "non-finite");
}

}  // namespace
}  // namespace watergs
