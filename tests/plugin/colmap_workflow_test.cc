// PlanReconstruction: the settings `reconstruct` chooses for a photo count,
// and that options given override them.
#include "plugin/colmap_workflow.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

namespace watergs {
namespace {

// `n` photos of one size (480x360) without EXIF, or two sizes.
PhotoCameras Cameras(int n, bool in_capture_order, bool one_size = true) {
  std::vector<PhotoDescription> photos(n, PhotoDescription{480, 360, {}});
  if (!one_size) photos[1].width = 360;
  return GroupPhotosByCamera(photos, in_capture_order);
}

TEST(PlanReconstruction, MatchesEveryPairUpToTheLimitThenNeighbours) {
  const ReconstructOptions automatic;
  // The demo's 48 photos: every pair (sequential placed some wrongly).
  const ColmapPlan demo =
      PlanReconstruction(48, 2, false, Cameras(48, true), automatic);
  EXPECT_EQ(demo.matcher, "exhaustive");
  EXPECT_NE(demo.reasons[0].find("1128 pairs"), std::string::npos)
      << demo.reasons[0];
  EXPECT_EQ(PlanReconstruction(kMaxExhaustivePhotos, 2, false,
                               Cameras(kMaxExhaustivePhotos, true), automatic)
                .matcher,
            "exhaustive");
  const ColmapPlan walk =
      PlanReconstruction(kMaxExhaustivePhotos + 1, 2, false,
                         Cameras(kMaxExhaustivePhotos + 1, true), automatic);
  EXPECT_EQ(walk.matcher, "sequential");
  EXPECT_NE(walk.reasons[0].find("1055 pairs"), std::string::npos)
      << walk.reasons[0];
  EXPECT_EQ(demo.max_features, 2048);
  EXPECT_EQ(PlanReconstruction(48, 2, true, Cameras(48, true), automatic)
                .max_features,
            8192);
}

TEST(PlanReconstruction, OptionsGivenOverrideTheChoice) {
  ReconstructOptions given;
  given.matcher = "sequential";
  given.max_features = 1024;
  const ColmapPlan plan =
      PlanReconstruction(48, 2, false, Cameras(48, true), given);
  EXPECT_EQ(plan.matcher, "sequential");
  EXPECT_EQ(plan.max_features, 1024);
  EXPECT_NE(plan.reasons[0].find("(--matcher)"), std::string::npos);
  EXPECT_NE(plan.reasons[1].find("(--max_features)"), std::string::npos);
}

TEST(NamedInCaptureOrder, ANumberedSequenceIsAnOrderAWebCollectionIsNot) {
  EXPECT_TRUE(NamedInCaptureOrder(
      {"a/view_000.jpg", "a/view_001.jpg", "a/view_010.jpg"}));
  EXPECT_TRUE(NamedInCaptureOrder({"IMG_4026.JPG", "IMG_4027.JPG"}));
  EXPECT_TRUE(NamedInCaptureOrder({"0001.png", "0002.png"}));
  // Timestamps (LLFF's room, phones).
  EXPECT_TRUE(NamedInCaptureOrder(
      {"DJI_20200223_163016_842.jpg", "DJI_20200223_163017_120.jpg"}));
  EXPECT_TRUE(NamedInCaptureOrder(
      {"PXL_20231105_143022123.jpg", "PXL_20231105_143107554.jpg"}));
  // Another prefix (two captures), a name without a number, a number twice.
  EXPECT_FALSE(NamedInCaptureOrder({"IMG_0001.JPG", "DSC_0002.JPG"}));
  EXPECT_FALSE(NamedInCaptureOrder({"IMG_0001.JPG", "IMG_cover.JPG"}));
  EXPECT_FALSE(NamedInCaptureOrder({"IMG_0001.JPG", "IMG_1.JPG"}));
  EXPECT_FALSE(NamedInCaptureOrder({"a8f3c2.jpg", "29b1e0.jpg", "77d0aa.jpg"}));
}

TEST(PlanReconstruction, PhotosInNoOrderAreMatchedEveryPairWithACameraEach) {
  ReconstructOptions automatic;
  automatic.sequential_above = 20;
  const ColmapPlan ordered = PlanReconstruction(48, 2, false, Cameras(48, true),
                                                automatic, false, true);
  EXPECT_EQ(ordered.matcher, "sequential");
  EXPECT_TRUE(ordered.single_camera);
  EXPECT_FALSE(ordered.camera_per_photo);
  const ColmapPlan unordered = PlanReconstruction(
      48, 2, false, Cameras(48, false), automatic, false, false);
  EXPECT_EQ(unordered.matcher, "exhaustive");
  EXPECT_FALSE(unordered.single_camera);
  EXPECT_TRUE(unordered.camera_per_photo);
  EXPECT_NE(unordered.reasons[0].find("no capture order"), std::string::npos)
      << unordered.reasons[0];
  // 135 photos: 9,045 pairs at 0.07 CPU-seconds each on 2 threads.
  const ColmapPlan web = PlanReconstruction(135, 2, false, Cameras(135, false),
                                            ReconstructOptions(), false, false);
  EXPECT_NE(web.reasons[0].find("9045 pairs"), std::string::npos);
  EXPECT_NE(web.reasons[0].find("~5 min on 2 threads, an estimate from the "
                                "demo scene's 0.07 CPU-s a pair on a 2-core "
                                "machine)"),
            std::string::npos)
      << web.reasons[0];
  EXPECT_NE(unordered.reasons[2].find("a camera per photo"), std::string::npos)
      << unordered.reasons[2];
  // Photos of several sizes in order: a camera each (no EXIF to group by).
  const ColmapPlan sizes = PlanReconstruction(
      48, 2, false, Cameras(48, true, false), ReconstructOptions());
  EXPECT_FALSE(sizes.single_camera);
  EXPECT_TRUE(sizes.camera_per_photo);
}

TEST(PlanReconstruction, SaysHowManyEXIFCamerasItFound) {
  const ExifCamera canon{"Canon", "Canon EOS 5D", 24}, phone{"Apple", "x", 4};
  const PhotoCameras two = GroupPhotosByCamera(
      {{480, 360, canon}, {480, 360, canon}, {480, 360, phone}}, false);
  const ColmapPlan plan =
      PlanReconstruction(3, 2, false, two, ReconstructOptions(), false, false);
  EXPECT_TRUE(plan.camera_per_photo);
  EXPECT_NE(plan.reasons[2].find("2 cameras for 3 photos, one per EXIF camera "
                                 "and size"),
            std::string::npos)
      << plan.reasons[2];
  const PhotoCameras one = GroupPhotosByCamera(
      {{480, 360, canon}, {480, 360, canon}, {480, 360, canon}}, true);
  const ColmapPlan walk =
      PlanReconstruction(3, 2, false, one, ReconstructOptions(), false, true);
  EXPECT_TRUE(walk.single_camera);
  EXPECT_NE(walk.reasons[2].find("one camera (photos share one size and EXIF "
                                 "camera)"),
            std::string::npos)
      << walk.reasons[2];
}

}  // namespace
}  // namespace watergs

namespace watergs {
namespace {

// The demo's sequentially matched model (two groups of photos joined half a
// turn wrong) read 14-16 dB on three held-out views and 22-24 dB on the rest;
// the exhaustively matched one 25.4-26.0 dB on all six.
TEST(OutlierViewWarning, NamesTheViewsFarBelowTheBestOnly) {
  const std::string misplaced = R"({"psnr": 19.0, "views": [
      {"name": "view_000.jpg", "psnr": 14.36},
      {"name": "view_008.jpg", "psnr": 13.94},
      {"name": "view_016.jpg", "psnr": 16.51},
      {"name": "view_024.jpg", "psnr": 22.45},
      {"name": "view_032.jpg", "psnr": 23.82},
      {"name": "view_040.jpg", "psnr": 22.98}]})";
  const std::string warning = OutlierViewWarning(misplaced);
  EXPECT_NE(warning.find("view_000.jpg 14.4 dB, view_008.jpg 13.9 dB, "
                         "view_016.jpg 16.5 dB."),
            std::string::npos)
      << warning;
  EXPECT_EQ(warning.find("view_024"), std::string::npos) << warning;
  EXPECT_NE(warning.find("best (23.8 dB)"), std::string::npos) << warning;
  EXPECT_EQ(std::count(warning.begin(), warning.end(), '\n'), 1);
  const std::string placed = R"({"views": [
      {"name": "view_000.jpg", "psnr": 25.8}, {"name": "view_008.jpg",
      "psnr": 26.0}, {"name": "view_032.jpg", "psnr": 25.4}]})";
  EXPECT_EQ(OutlierViewWarning(placed), "");
  EXPECT_EQ(OutlierViewWarning("not json"), "");
  EXPECT_EQ(OutlierViewWarning(R"({"psnr": 20})"), "");
  // A view without a number (NaN is written as null) is left out, not fatal.
  const std::string odd = OutlierViewWarning(R"({"views": [7, {"psnr": null},
      {"name": "a.jpg", "psnr": 25.0}, {"name": 3, "psnr": 12.0}]})");
  EXPECT_NE(odd.find("? 12.0 dB."), std::string::npos) << odd;
  EXPECT_EQ(odd.find("a.jpg"), std::string::npos) << odd;
}

}  // namespace
}  // namespace watergs
