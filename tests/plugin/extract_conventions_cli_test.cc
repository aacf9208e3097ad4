// `extract --render_conventions NAME` (issue 54): the views are read as the
// named renderer shows them, the suspect's and the raw model's alike, so a
// viewer's screenshot can be simulated at the workspace's cameras without a
// browser. Checked against the decoder run in-process on the CPU
// rasterizer's renders under the same conventions; an unknown name fails in
// one line before any work.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "gaussian/formats/ply_io.h"
#include "gaussian/rasterizer.h"
#include "gaussian/render_conventions.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "tests/plugin/rendered_workspace.h"
#include "watermark/bit_decoder.h"

namespace watergs {
namespace {

using testing::ExpectOneLineError;
using testing::RunCommand;
using testing::TempDir;
using testing::WatergsBin;

const std::string kDecoder =
    std::string(WATERGS_SOURCE_DIR) + "/watermark/models/decoder_48.bin";

// Each workspace view's logits from renders under `conventions`.
std::vector<std::vector<float>> LogitsUnder(
    const GaussianModel& model, const Workspace& workspace,
    const RenderConventions& conventions) {
  std::unique_ptr<BitDecoder> decoder = LoadBitDecoder(kDecoder, Device::kCpu);
  auto rasterizer = MakeCpuRasterizer();
  RenderOptions options;
  options.conventions = conventions;
  const WorkspaceViews views(workspace);
  std::vector<std::vector<float>> logits;
  for (size_t v = 0; v < views.NumViews(); ++v) {
    ImageRGB image;
    rasterizer->Forward(model, views.Camera(v), options, &image, nullptr);
    for (float& value : image.data) value = std::clamp(value, 0.f, 1.f);
    logits.push_back(decoder->Logits(image));
  }
  return logits;
}

std::vector<std::vector<float>> JsonLogits(const nlohmann::json& j) {
  std::vector<std::vector<float>> logits;
  for (const auto& view : j["views"]) {
    logits.push_back(view["logits"].get<std::vector<float>>());
  }
  return logits;
}

TEST(ExtractConventionsCli, ReadsTheViewsAsTheNamedRendererShowsThem) {
  TempDir dir("extract_conventions");
  GaussianModel model;
  WorkspaceOptions wo;
  wo.workspace_path = testing::MakeRenderedWorkspace(
      dir / "ws", testing::SmallSceneOptions(), &model);
  // Splats below a pixel: the web set's eigenvalue floor changes them.
  for (float& log_scale : model.log_scales) log_scale -= 2.5f;
  WritePly(dir / "model.ply", model);
  const Workspace workspace = Workspace::Open(wo);

  const std::string base = WatergsBin() + " extract --input_path " +
                           (dir / "model.ply") + " --workspace_path " +
                           wo.workspace_path + " --decoder " + kDecoder +
                           " --align off --num_threads 2";
  for (const std::string name : {"watergs", "web", "playcanvas"}) {
    const std::string json = dir / (name + ".json");
    const auto run =
        RunCommand(base + " --render_conventions " + name + " --json " + json);
    ASSERT_EQ(run.exit_code, 0) << run.output;
    std::ifstream in(json);
    const nlohmann::json j = nlohmann::json::parse(in);
    EXPECT_EQ(j["render_conventions"], name);
    const auto expected = LogitsUnder(
        model, workspace, FindRenderConventions(name, "test").conventions);
    const auto read = JsonLogits(j);
    ASSERT_EQ(read.size(), expected.size()) << name;
    for (size_t v = 0; v < read.size(); ++v) {
      ASSERT_EQ(read[v].size(), expected[v].size());
      for (size_t i = 0; i < read[v].size(); ++i) {
        EXPECT_NEAR(read[v][i], expected[v][i], 1e-4) << name << " " << v;
      }
    }
    EXPECT_EQ(
        run.output.find(" as " + name + " renders them") != std::string::npos,
        name != "watergs")
        << run.output;
  }
  // The sets read differently on this model (the check above could not
  // tell them apart otherwise).
  const auto plain = LogitsUnder(model, workspace, RenderConventions());
  const auto web = LogitsUnder(
      model, workspace, FindRenderConventions("web", "test").conventions);
  EXPECT_NE(plain, web);
  EXPECT_NE(
      plain,
      LogitsUnder(model, workspace,
                  FindRenderConventions("playcanvas", "test").conventions));

  // The owner's reading renders the raw model under the same conventions:
  // each logit is the suspect's minus the raw model's, both as web shows
  // them (a tie, |difference| below detect's tie logit, reads 0).
  GaussianModel suspect = model;
  for (float& dc : suspect.sh_dc) dc += 0.3f;
  WritePly(dir / "suspect.ply", suspect);
  const std::string owner_json = dir / "owner.json";
  const auto owner = RunCommand(
      WatergsBin() + " extract --input_path " + (dir / "suspect.ply") +
      " --raw_path " + (dir / "model.ply") + " --workspace_path " +
      wo.workspace_path + " --decoder " + kDecoder +
      " --align off --num_threads 2 --render_conventions web --json " +
      owner_json);
  ASSERT_EQ(owner.exit_code, 0) << owner.output;
  std::ifstream in(owner_json);
  const auto read = JsonLogits(nlohmann::json::parse(in)["owner"]);
  const auto web_suspect = LogitsUnder(
      suspect, workspace, FindRenderConventions("web", "test").conventions);
  ASSERT_EQ(read.size(), web.size());
  int compared = 0;
  for (size_t v = 0; v < read.size(); ++v) {
    for (size_t i = 0; i < read[v].size(); ++i) {
      const float difference = web_suspect[v][i] - web[v][i];
      if (read[v][i] == 0.f) continue;  // a tie
      EXPECT_NEAR(read[v][i], difference, 1e-4) << v << " " << i;
      ++compared;
    }
  }
  EXPECT_GT(compared, 100);

  ExpectOneLineError(RunCommand(base + " --render_conventions webb"),
                     "--render_conventions: unknown render conventions 'webb'");
}

}  // namespace
}  // namespace watergs
