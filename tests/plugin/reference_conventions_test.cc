// The owner's reference's candidate conventions
// (plugin/reference_conventions.h): "auto" is the whole registry, watergs'
// first; the reference closest to the image wins, watergs' own on a tie.
#include "plugin/reference_conventions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

ImageRGB Filled(float value) {
  ImageRGB image(8, 6);
  std::fill(image.data.begin(), image.data.end(), value);
  return image;
}

TEST(ReferenceConventions, AutoIsEveryRegisteredSetWatergsFirst) {
  const std::vector<NamedRenderConventions> all = ReferenceCandidates("auto");
  ASSERT_EQ(all.size(), RenderConventionsRegistry().size());
  EXPECT_EQ(all[0].name, "watergs");
  for (size_t k = 0; k < all.size(); ++k) {
    EXPECT_EQ(all[k].name, RenderConventionsRegistry()[k].name);
  }
  const std::vector<NamedRenderConventions> web = ReferenceCandidates("web");
  ASSERT_EQ(web.size(), 1u);
  EXPECT_EQ(web[0].name, "web");
  try {
    ReferenceCandidates("gs3d");
    FAIL() << "an unknown name was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--reference_conventions: unknown render conventions 'gs3d' "
              "(one of watergs, web, playcanvas)");
  }
}

TEST(ReferenceConventions, TheClosestReferenceWinsAndTiesGoToTheFirst) {
  const ImageRGB image = Filled(0.5f);
  const ReferenceChoice far_first =
      ChooseReference(image, {Filled(0.4f), Filled(0.49f), Filled(0.7f)});
  EXPECT_EQ(far_first.best, 1u);
  ASSERT_EQ(far_first.psnr.size(), 3u);
  EXPECT_NEAR(far_first.psnr[0], 20.0, 1e-4);  // 0.1 off everywhere
  EXPECT_NEAR(far_first.psnr[1], 40.0, 1e-3);
  const ReferenceChoice tie =
      ChooseReference(image, {Filled(0.25f), Filled(0.75f)});
  EXPECT_EQ(tie.best, 0u);
  const ReferenceChoice exact =
      ChooseReference(image, {Filled(0.5f), Filled(0.5f)});
  EXPECT_EQ(exact.best, 0u);
  EXPECT_TRUE(std::isinf(exact.psnr[0]));
  EXPECT_THROW(ChooseReference(image, {}), Error);
}

}  // namespace
}  // namespace watergs
