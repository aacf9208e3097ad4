// Tests of the owner's reference for image files (plugin/suspect_reference.h):
// the JPEG quality read from a file's tables, and the raw model's render sent
// the way a shared copy went, which is what makes the difference reading
// cancel the scene.
#include "plugin/suspect_reference.h"

#include <gtest/gtest.h>

#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "tests/gaussian/rasterizer_test_scenes.h"
#include "tests/plugin/synthetic_model.h"
#include "watermark/evaluation.h"
#include "watermark/image_attacks.h"

namespace watergs {
namespace {

cv::Mat Texture(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  std::mt19937 rng(2);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        image.at<cv::Vec3b>(y, x)[c] = uint8_t((x * 7 + y * 3 * c) % 256);
      }
    }
  }
  return image;
}

TEST(SuspectReference, ReadsTheJpegQualityFromTheFilesTables) {
  testing::TempDir dir("suspect_reference");
  for (int quality : {10, 30, 50, 75, 90, 97, 100}) {
    const std::string path = dir / ("q" + std::to_string(quality) + ".jpg");
    ASSERT_TRUE(cv::imwrite(path, Texture(40, 30),
                            {cv::IMWRITE_JPEG_QUALITY, quality}));
    EXPECT_EQ(JpegQualityOf(path), quality) << path;
  }
  // Not a JPEG, a missing file, a truncated header: no quality.
  const std::string png = dir / "image.png";
  ASSERT_TRUE(cv::imwrite(png, Texture(40, 30)));
  EXPECT_EQ(JpegQualityOf(png), 0);
  EXPECT_EQ(JpegQualityOf(dir / "missing.jpg"), 0);
  const std::string cut = dir / "cut.jpg";
  {
    std::vector<uint8_t> bytes;
    cv::imencode(".jpg", Texture(40, 30), bytes);
    std::FILE* f = std::fopen(cut.c_str(), "wb");
    std::fwrite(bytes.data(), 1, 30, f);
    std::fclose(f);
  }
  EXPECT_EQ(JpegQualityOf(cut), 0);
}

// Mean absolute difference of two images of one size.
double MeanAbsDifference(const ImageRGB& a, const ImageRGB& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  double sum = 0;
  for (size_t i = 0; i < a.data.size(); ++i)
    sum += std::abs(a.data[i] - b.data[i]);
  return sum / a.data.size();
}

TEST(SuspectReference, TheRenderSentTheWayACopyWentCancelsIt) {
  // A copy shared at 3/4 size as JPEG 85, decoded back at the render size:
  // the raw model's render sent the same way is that image (the model is
  // the same here, so only the way matters); a plain render differs by the
  // copy's blur and blocks.
  const RenderCamera small = testing::RandomCamera(90, 66, 5);
  testing::SceneSpec spec;
  spec.count = 600;
  spec.width = small.width;
  spec.height = small.height;
  spec.sh_degree = 0;
  const GaussianModel model = testing::RandomScene(small, spec, 9);
  const std::unique_ptr<Rasterizer> rasterizer = MakeRasterizer(Device::kCpu);
  const CameraRenderer render = [&](const RenderCamera& camera) {
    return RenderClamped(*rasterizer, model, camera, {0.f, 0.f, 0.f});
  };
  const ImageRGB copy = ResizeTo(
      ApplyImageAttack({ImageAttackKind::kJpeg, 85}, render(small)), 120, 88);
  RenderCamera decoded = small;  // the camera of the copy as decoded
  decoded.width = 120;
  decoded.height = 88;
  decoded.fx *= 120.0 / 90;
  decoded.cx *= 120.0 / 90;
  decoded.fy *= 88.0 / 66;
  decoded.cy *= 88.0 / 66;
  const double sent =
      MeanAbsDifference(RenderLikeSuspect(render, decoded, {90, 66, 85}), copy);
  const double plain = MeanAbsDifference(render(decoded), copy);
  const double size_only =
      MeanAbsDifference(RenderLikeSuspect(render, decoded, {90, 66, 0}), copy);
  EXPECT_LT(sent, 0.002);
  EXPECT_GT(plain, 10 * sent);
  EXPECT_GT(size_only, 2 * sent);
  // Nothing known about the copy: the plain render.
  EXPECT_EQ(RenderLikeSuspect(render, decoded, {}).data, render(decoded).data);
}

}  // namespace
}  // namespace watergs
