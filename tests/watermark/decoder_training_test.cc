// Tests of the decoder-training schedule: the PSNR target ramp, linear or
// gated by the running bit accuracy.
#include "watermark/decoder_training.h"

#include <gtest/gtest.h>

namespace watergs {
namespace {

DecoderTrainingOptions RampOptions() {
  DecoderTrainingOptions options;
  options.target_psnr_start = 10.f;
  options.target_psnr = 30.f;
  options.psnr_ramp_steps = 100;
  return options;
}

TEST(PsnrTargetTest, LinearRampReachesTheTargetAndStays) {
  const DecoderTrainingOptions options = RampOptions();
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 0, 0.5, 0.f), 10.f);
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 50, 0.5, 0.f), 20.f);
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 100, 0.5, 0.f), 30.f);
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 5000, 0.5, 0.f), 30.f);
}

TEST(PsnrTargetTest, GatedRampWaitsForTheDecoder) {
  DecoderTrainingOptions options = RampOptions();
  options.accuracy_gate = 0.9f;
  // Below the gate the target holds, whatever the step.
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 5000, 0.89, 12.f), 12.f);
  // At the gate it advances by one ramp step (20 dB / 100 steps).
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 3, 0.95, 12.f), 12.2f);
  // And never overshoots the final target.
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 3, 0.99, 29.9f), 30.f);
}

TEST(PsnrTargetTest, NoRampMeansTheFinalTarget) {
  DecoderTrainingOptions options = RampOptions();
  options.psnr_ramp_steps = 0;
  options.accuracy_gate = 0.9f;
  EXPECT_FLOAT_EQ(NextPsnrTarget(options, 0, 0.0, 10.f), 30.f);
}

}  // namespace
}  // namespace watergs
