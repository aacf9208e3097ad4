// Tests of the per-scene choice of distortion layers: when reviews may
// judge, which bits count as broken, when a layer turns on, and its state.
#include "watermark/distortion_choice.h"

#include <gtest/gtest.h>

#include <vector>

#include "gaussian/util/error.h"

namespace watergs {
namespace {

std::vector<DistortionSpec> Candidates() {
  return ParseDistortionList("identity,gn:0.01,dropout:0.1,crop:0.1");
}

TEST(DistortionChoice, StartsWithThePlainRenderOnlyAndDropsTheIdentity) {
  DistortionChoice choice(Candidates());
  ASSERT_EQ(choice.candidates().size(), 3u);
  EXPECT_EQ(ToString(choice.candidates()[0].spec), "gn:0.01");
  const std::vector<DistortionSpec> simulated = choice.Simulated();
  ASSERT_EQ(simulated.size(), 1u);
  EXPECT_EQ(simulated[0].kind, DistortionKind::kIdentity);
}

// Ready: every bit of the check views (the first num_views cameras) reads
// past the margin; the free viewpoints after them do not count.
TEST(DistortionChoice, ReviewsWaitUntilEveryCheckViewReadsPastTheMargin) {
  const Bits message = {1, 0, 1};
  const std::vector<std::vector<float>> reads = {{2, -1, 0.5f}, {1, -3, 4}};
  EXPECT_TRUE(DistortionChoice::Ready(reads, 2, message, 0));
  EXPECT_TRUE(DistortionChoice::Ready(reads, 2, message, 0.5));
  EXPECT_FALSE(DistortionChoice::Ready(reads, 2, message, 0.6));
  std::vector<std::vector<float>> one_wrong = reads;
  one_wrong[1][1] = 0.2f;  // Bit 0 read as 1.
  EXPECT_FALSE(DistortionChoice::Ready(one_wrong, 2, message, 0));
  EXPECT_TRUE(DistortionChoice::Ready(one_wrong, 1, message, 0));
  EXPECT_FALSE(DistortionChoice::Ready(reads, 0, message, 0));
  EXPECT_FALSE(DistortionChoice::Ready(reads, 3, message, 0));
  // A zero logit reads bit 0 (as the decoder reads) but is no margin.
  EXPECT_TRUE(DistortionChoice::Ready({{1, 0, 1}}, 1, message, 0));
  EXPECT_FALSE(DistortionChoice::Ready({{1, 0, 1}}, 1, message, 0.01));
}

// More than kBrokenShare of the read bits: with 200 read, 2 broken is 1%
// (kept off), 3 is over it.
TEST(DistortionChoice, ABitOrTwoBrokenInAHundredIsLeftToAggregation) {
  const Bits message(100, 1);
  const std::vector<std::vector<float>> plain(2, std::vector<float>(100, 1.f));
  std::vector<std::vector<float>> through = plain;
  through[0][3] = through[1][7] = -0.5f;
  DistortionChoice choice(Candidates());
  EXPECT_FALSE(choice.Review(0, 250, message, plain, through));
  EXPECT_EQ(choice.candidates()[0].broken_bits, 2);
  EXPECT_EQ(choice.candidates()[0].read_bits, 200);
  EXPECT_EQ(choice.candidates()[0].short_reviews, 0);
  through[1][8] = -0.5f;
  EXPECT_FALSE(choice.Review(0, 500, message, plain, through));
  EXPECT_EQ(choice.candidates()[0].short_reviews, 1);
  EXPECT_TRUE(choice.Review(0, 750, message, plain, through));
  EXPECT_EQ(choice.candidates()[0].since, 750);
}

// Broken: read by the plain render and wrong through the layer. A bit the
// plain render already misses does not count against the layer. A layer
// is simulated at the second review in a row that finds it short.
TEST(DistortionChoice, ALayerTurnsOnAtTheSecondReviewInARowThatFindsItShort) {
  const Bits message = {1, 0};
  const std::vector<std::vector<float>> plain = {{2, -1}, {1, 0.5f}};
  const std::vector<std::vector<float>> intact = {{1, -0.5f}, {1, 2}};
  const std::vector<std::vector<float>> broken = {{-0.1f, -1}, {1, 2}};
  DistortionChoice choice(Candidates());
  // View 1's bit 1 is wrong plainly and through the layer: nothing broken.
  EXPECT_FALSE(choice.Review(1, 250, message, plain, intact));
  EXPECT_EQ(choice.candidates()[1].broken_bits, 0);
  EXPECT_EQ(choice.candidates()[1].read_bits, 3);
  EXPECT_DOUBLE_EQ(choice.candidates()[1].weakest, -2.0);
  // View 0's bit 0 flips: short once, then not, then twice in a row.
  EXPECT_FALSE(choice.Review(1, 500, message, plain, broken));
  EXPECT_EQ(choice.candidates()[1].broken_bits, 1);
  EXPECT_EQ(choice.candidates()[1].short_reviews, 1);
  EXPECT_FALSE(choice.Review(1, 750, message, plain, intact));
  EXPECT_EQ(choice.candidates()[1].short_reviews, 0);
  EXPECT_FALSE(choice.Review(1, 1000, message, plain, broken));
  EXPECT_EQ(choice.Simulated().size(), 1u);
  EXPECT_TRUE(choice.Review(1, 1250, message, plain, broken));
  EXPECT_EQ(choice.candidates()[1].since, 1250);
  ASSERT_EQ(choice.Simulated().size(), 2u);
  EXPECT_EQ(ToString(choice.Simulated()[1]), "dropout:0.1");
  // Later reviews record figures but do not turn it on again.
  EXPECT_FALSE(choice.Review(1, 1500, message, plain, {{-1, 1}, {1, 2}}));
  EXPECT_EQ(choice.candidates()[1].broken_bits, 2);
  EXPECT_EQ(choice.candidates()[1].since, 1250);
  EXPECT_EQ(choice.candidates()[1].reviewed_at, 1500);
  EXPECT_THROW(choice.Review(3, 750, message, plain, plain), Error);
  EXPECT_THROW(choice.Review(0, 750, message, plain, {{2, -1}}), Error);
  EXPECT_THROW(choice.Review(0, 750, message, {}, {}), Error);
}

// Draws of a layer count together: camera v's draw d at d * cameras + v,
// each against camera v's plain reading.
TEST(DistortionChoice, DrawsAreJudgedTogetherAgainstTheirCamerasPlainReading) {
  const Bits message = {1, 0};
  const std::vector<std::vector<float>> plain = {{2, -1}, {1, 0.5f}};
  // Draw 0 breaks nothing; draw 1 breaks camera 0's bit 1 and camera 1's
  // bit 0 (its bit 1 was wrong plainly and does not count).
  const std::vector<std::vector<float>> draws = {
      {2, -1}, {1, 1}, {2, 0.5f}, {-1, 1}};
  DistortionChoice choice(Candidates());
  EXPECT_FALSE(choice.Review(2, 500, message, plain, draws));
  EXPECT_EQ(choice.candidates()[2].read_bits, 6);
  EXPECT_EQ(choice.candidates()[2].broken_bits, 2);
  EXPECT_EQ(choice.candidates()[2].short_reviews, 1);
  EXPECT_DOUBLE_EQ(choice.candidates()[2].weakest, -1.0);
  EXPECT_THROW(choice.Review(2, 750, message, plain, {{2, -1}, {1, 1}, {2, 0}}),
               Error);
}

TEST(DistortionChoice, SummaryNamesEachCandidatesOutcome) {
  const Bits message = {1};
  DistortionChoice choice(Candidates());
  choice.Review(0, 250, message, {{3}}, {{2.5f}});
  choice.Review(1, 250, message, {{3}}, {{-0.25f}});
  choice.Review(1, 500, message, {{3}}, {{-0.25f}});
  choice.Review(2, 500, message, {{3}}, {{-0.5f}});
  const std::string summary = choice.Summary();
  EXPECT_NE(summary.find("gn:0.01 not needed (at iteration 250 through it: 0 "
                         "of 1 read bits broken, weakest +2.50)"),
            std::string::npos)
      << summary;
  EXPECT_NE(summary.find("dropout:0.1 from iteration 500"), std::string::npos)
      << summary;
  EXPECT_NE(summary.find("crop:0.1 short at the latest review only"),
            std::string::npos)
      << summary;
  // A run that ended at iteration 500 never simulated dropout.
  EXPECT_NE(choice.Summary(500).find("dropout:0.1 short at the last check "
                                     "(iteration 500): never simulated"),
            std::string::npos)
      << choice.Summary(500);
  EXPECT_NE(choice.Summary(750).find("dropout:0.1 from iteration 500"),
            std::string::npos);
  EXPECT_EQ(DistortionChoice(Candidates())
                .Summary()
                .find("gn:0.01 not reviewed (the check views never read)"),
            0u);
}

TEST(DistortionChoice, StateRestoresAndRefusesAnotherRunsState) {
  DistortionChoice choice(Candidates());
  choice.Review(0, 500, {1}, {{1}}, {{-1}});
  choice.Review(2, 500, {1}, {{1}}, {{-1}});
  choice.Review(2, 750, {1}, {{1}}, {{-1}});
  // Per candidate: turned on at, short reviews in a row.
  const std::vector<int64_t> state = choice.State();
  EXPECT_EQ(state, (std::vector<int64_t>{-1, 1, -1, 0, 750, 2}));
  DistortionChoice restored(Candidates());
  ASSERT_TRUE(restored.Restore(state));
  ASSERT_EQ(restored.Simulated().size(), 2u);
  EXPECT_EQ(ToString(restored.Simulated()[1]), "crop:0.1");
  // The restored streak counts on: gn turns on at its next short review.
  EXPECT_TRUE(restored.Review(0, 1000, {1}, {{1}}, {{-1}}));
  DistortionChoice fresh(Candidates());
  EXPECT_FALSE(fresh.Restore({-1, 0, 750, 2}));
  EXPECT_FALSE(fresh.Restore({-1, 0, -2, 0, 750, 2}));
  EXPECT_FALSE(fresh.Restore({-1, -1, -1, 0, 750, 2}));
  EXPECT_EQ(fresh.State(), (std::vector<int64_t>{-1, 0, -1, 0, -1, 0}))
      << "a refusal changes nothing";
}

}  // namespace
}  // namespace watergs
