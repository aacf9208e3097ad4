// The random-feature decoder: forward values and input gradient against an
// independent double-precision reference (central differences), the
// calibration's whitening (logits zero-mean, uncorrelated, of the stated
// scale on the calibration crops), its weights file (round trip, refusals),
// and steerability and balance on held-out photos.
#include "watermark/feature_decoder.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

#include "gaussian/util/error.h"
#include "watermark/bit_decoder.h"
#include "watermark/decoder.h"
#include "watermark/decoder_training.h"
#include "watermark/feature_decoder_calibration.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";

// Plain double-precision D(x) for an image in [0,1] (HWC), written from the
// definition in feature_decoder.h, not from the layers.
std::vector<double> ReferenceLogits(const FeatureNet& net,
                                    const std::vector<double>& image, int width,
                                    int height) {
  const FeatureDecoderConfig& cfg = net.config();
  const int p = cfg.pool, k = cfg.kernel, h = height / p, w = width / p;
  std::vector<double> pooled(3 * h * w, 0.0);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h * p; ++y)
      for (int x = 0; x < w * p; ++x)
        pooled[(c * h + y / p) * w + x / p] +=
            (2 * image[(y * width + x) * 3 + c] - 1) / (p * p);
  if (cfg.highpass > 0) {
    // Minus the mean over the (2r+1)^2 box clipped to the pooled image.
    const int r = cfg.highpass;
    std::vector<double> residual(pooled.size());
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          double sum = 0;
          int count = 0;
          for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy)
            for (int xx = std::max(0, x - r); xx <= std::min(w - 1, x + r);
                 ++xx)
              sum += pooled[(c * h + yy) * w + xx], ++count;
          residual[(c * h + y) * w + x] =
              pooled[(c * h + y) * w + x] - sum / count;
        }
    pooled = residual;
  }
  std::vector<double> features(cfg.channels, 0.0);
  for (int o = 0; o < cfg.channels; ++o) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double sum = net.conv.bias.value[o];
        for (int c = 0; c < 3; ++c)
          for (int dy = 0; dy < k; ++dy)
            for (int dx = 0; dx < k; ++dx) {
              const int yy = y + dy - k / 2, xx = x + dx - k / 2;
              if (yy < 0 || yy >= h || xx < 0 || xx >= w) continue;
              sum += net.conv.weight.value[((o * 3 + c) * k + dy) * k + dx] *
                     pooled[(c * h + yy) * w + xx];
            }
        features[o] += std::max(sum, 0.0) / (h * w);
      }
    }
  }
  std::vector<double> logits(cfg.num_bits);
  for (int b = 0; b < cfg.num_bits; ++b) {
    logits[b] = net.linear.bias.value[b];
    for (int o = 0; o < cfg.channels; ++o)
      logits[b] += net.linear.weight.value[b * cfg.channels + o] * features[o];
  }
  return logits;
}

std::unique_ptr<FeatureNet> RandomNet(const FeatureDecoderConfig& config,
                                      uint32_t seed) {
  auto net = std::make_unique<FeatureNet>(config, seed);
  std::mt19937 rng(seed + 1);
  std::normal_distribution<float> normal(0.f, 1.f);
  for (float& v : net->linear.weight.value) v = normal(rng);
  for (float& v : net->linear.bias.value) v = normal(rng);
  return net;
}

ImageRGB RandomImage(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  ImageRGB image(width, height);
  for (float& v : image.data) v = u(rng);
  return image;
}

TEST(FeatureDecoderTest, ForwardAndInputGradientMatchDoubleReference) {
  for (const auto& [pool, highpass] : std::vector<std::pair<int, int>>{
           {1, 0}, {2, 0}, {3, 0}, {1, 1}, {2, 2}}) {
    FeatureDecoderConfig config{3, 5, pool, 3, highpass};
    FeatureDecoder decoder(RandomNet(config, 7 + pool + 10 * highpass));
    // Not a multiple of the pool: the dropped border must get no gradient.
    // Wider than the high-pass box, so that both clipped and whole boxes occur.
    const int width = 6 * pool + (pool > 1), height = 5 * pool + (pool > 1);
    const ImageRGB image = RandomImage(width, height, 3);
    std::vector<double> x(image.data.begin(), image.data.end());
    const std::vector<double> want =
        ReferenceLogits(decoder.net(), x, width, height);
    const std::vector<float> got = decoder.Logits(image);
    for (int b = 0; b < 3; ++b)
      EXPECT_NEAR(got[b], want[b], 1e-4 * (1 + std::abs(want[b]))) << pool;

    const std::vector<float> dlogits = {0.7f, -1.3f, 0.4f};
    ImageRGB grad;
    decoder.InputGradient(image, dlogits, &grad);
    double max_error = 0, max_value = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      const double saved = x[i], step = 1e-6;
      auto loss = [&] {
        const auto z = ReferenceLogits(decoder.net(), x, width, height);
        return dlogits[0] * z[0] + dlogits[1] * z[1] + dlogits[2] * z[2];
      };
      x[i] = saved + step;
      const double plus = loss();
      x[i] = saved - step;
      const double minus = loss();
      x[i] = saved;
      const double numeric = (plus - minus) / (2 * step);
      max_error = std::max(max_error, std::abs(numeric - grad.data[i]));
      max_value = std::max(max_value, std::abs(numeric));
    }
    EXPECT_GT(max_value, 1e-3) << pool;
    EXPECT_LT(max_error, 1e-4 * max_value) << "pool " << pool;
  }
}

// A single image goes through the convolution in strips of rows when its
// output is large; any strip height gives the whole image's logits and input
// gradient (to float rounding), the halo rows included.
TEST(FeatureDecoderTest, StripsMatchTheWholeImage) {
  struct Case {
    int pool, kernel, highpass;
  };
  for (const Case& c : std::vector<Case>{{1, 3, 0}, {2, 3, 2}, {1, 5, 1}}) {
    const FeatureDecoderConfig config{4, 16, c.pool, c.kernel, c.highpass};
    const uint32_t seed = 11 + c.kernel + c.pool;
    FeatureDecoder whole(RandomNet(config, seed));
    const int width = 37, height = 29;
    const ImageRGB image = RandomImage(width, height, 5);
    const std::vector<float> dlogits = {0.7f, -1.3f, 0.4f, 2.1f};
    const std::vector<float> want = whole.Logits(image);
    EXPECT_EQ(whole.net().last_num_strips(), 1);
    ImageRGB want_grad;
    whole.InputGradient(image, dlogits, &want_grad);
    double grad_scale = 0;
    for (float v : want_grad.data)
      grad_scale = std::max(grad_scale, double(std::abs(v)));
    ASSERT_GT(grad_scale, 0);
    const size_t row_bytes = size_t(16) * (width / c.pool) * sizeof(float);
    for (int rows : {1, 2, 5, 9}) {
      FeatureDecoder strips(RandomNet(config, seed));
      strips.net().set_max_strip_bytes(row_bytes * (rows + 2 * (c.kernel / 2)));
      const std::vector<float> got = strips.Logits(image);
      EXPECT_EQ(strips.net().last_num_strips(),
                (height / c.pool + rows - 1) / rows);
      for (size_t b = 0; b < got.size(); ++b)
        EXPECT_NEAR(got[b], want[b], 1e-5 * (1 + std::abs(want[b])))
            << "rows " << rows << " kernel " << c.kernel;
      ImageRGB grad;
      strips.InputGradient(image, dlogits, &grad);
      ASSERT_EQ(grad.data.size(), want_grad.data.size());
      double worst = 0;
      for (size_t i = 0; i < grad.data.size(); ++i)
        worst =
            std::max(worst, double(std::abs(grad.data[i] - want_grad.data[i])));
      EXPECT_LT(worst, 1e-5 * grad_scale)
          << "rows " << rows << " kernel " << c.kernel << " pool " << c.pool;
    }
  }
}

TEST(FeatureDecoderTest, HighpassBackwardIsTheAdjointOfForward) {
  std::mt19937 rng(2);
  std::normal_distribution<float> normal(0.f, 1.f);
  for (int r : {1, 3, 20}) {
    Tensor x(2, 3, 11, 9), y, dy, dx;
    for (float& v : x.data) v = normal(rng);
    HighpassForward(x, r, &y);
    dy.ResizeLike(y);
    for (float& v : dy.data) v = normal(rng);
    HighpassBackward(dy, r, &dx);
    double lhs = 0, rhs = 0;
    for (size_t i = 0; i < y.size(); ++i) lhs += double(y.data[i]) * dy.data[i];
    for (size_t i = 0; i < x.size(); ++i) rhs += double(x.data[i]) * dx.data[i];
    EXPECT_NEAR(lhs, rhs, 1e-4 * (1 + std::abs(lhs))) << r;
  }
  // A flat image has no residual: the front end cannot lean on brightness.
  Tensor flat(1, 3, 7, 8), residual;
  flat.Fill(0.6f);
  HighpassForward(flat, 2, &residual);
  for (float v : residual.data) EXPECT_NEAR(v, 0.f, 1e-6f);
}

TEST(FeatureDecoderTest, AvgPoolBackwardIsTheAdjointOfForward) {
  std::mt19937 rng(1);
  std::normal_distribution<float> normal(0.f, 1.f);
  Tensor x(2, 3, 11, 9), y, dy, dx;
  for (float& v : x.data) v = normal(rng);
  AvgPoolForward(x, 4, &y);
  ASSERT_EQ(y.h, 2);
  ASSERT_EQ(y.w, 2);
  dy.ResizeLike(y);
  for (float& v : dy.data) v = normal(rng);
  AvgPoolBackward(dy, 4, x, &dx);
  double lhs = 0, rhs = 0;
  for (size_t i = 0; i < y.size(); ++i) lhs += double(y.data[i]) * dy.data[i];
  for (size_t i = 0; i < x.size(); ++i) rhs += double(x.data[i]) * dx.data[i];
  EXPECT_NEAR(lhs, rhs, 1e-5 * (1 + std::abs(lhs)));
  // Row 8 onwards and column 8 are outside every block.
  EXPECT_EQ(dx.Plane(1, 2)[10 * 9 + 3], 0.f);
  EXPECT_EQ(dx.Plane(0, 0)[2 * 9 + 8], 0.f);
}

FeatureCalibrationOptions SmallCalibration() {
  FeatureCalibrationOptions options;
  options.config = {16, 48, 4, 3};
  options.crop = 64;
  options.normalisation_crops = 64;
  options.feature_crops = 400;
  options.whiten_floor = 1e-9;
  options.logit_scale = 2.0;
  options.seed = 5;
  return options;
}

// Largest deviation of the logits' mean and covariance on `crops` from the
// white target (zero mean, covariance s^2 I), relative to s and s^2.
std::pair<double, double> WhitenessError(FeatureDecoder& decoder,
                                         const std::vector<ImageRGB>& crops,
                                         int bits, double scale) {
  Eigen::MatrixXd z(crops.size(), bits);
  for (size_t i = 0; i < crops.size(); ++i) {
    const std::vector<float> logits = decoder.Logits(crops[i]);
    for (int b = 0; b < bits; ++b) z(i, b) = logits[b];
  }
  const Eigen::RowVectorXd mean = z.colwise().mean();
  const Eigen::MatrixXd centred = z.rowwise() - mean;
  const Eigen::MatrixXd cov = centred.transpose() * centred / (z.rows() - 1);
  const double s2 = scale * scale;
  return {
      mean.cwiseAbs().maxCoeff() / scale,
      (cov - s2 * Eigen::MatrixXd::Identity(bits, bits)).cwiseAbs().maxCoeff() /
          s2};
}

TEST(FeatureDecoderCalibrationTest, LogitsAreWhiteOnTheCalibrationCrops) {
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  const FeatureCalibrationOptions options = SmallCalibration();
  FeatureCalibrationReport report;
  FeatureDecoder decoder(CalibrateFeatureDecoder(photos, options, &report));
  EXPECT_EQ(report.floored_eigenvalues, 0);
  // The same crops the covariance was taken over (seed + 2).
  const std::vector<ImageRGB> crops = SamplePhotoCrops(
      photos, options.crop, options.feature_crops, options.seed + 2);
  const auto [mean_error, cov_error] = WhitenessError(
      decoder, crops, options.config.num_bits, options.logit_scale);
  EXPECT_LT(mean_error, 1e-3);
  EXPECT_LT(cov_error, 1e-3);
}

// --calibration_blur: the whitening is taken over blurred crops, so the
// logits are white on exactly those (and a decoder calibrated on sharp
// crops is not: the option changes what "unmarked" looks like to it).
TEST(FeatureDecoderCalibrationTest, BlurredCalibrationIsWhiteOnBlurredCrops) {
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  FeatureCalibrationOptions options = SmallCalibration();
  options.calibration_blur = 3.0;
  FeatureDecoder blurred(CalibrateFeatureDecoder(photos, options));
  FeatureDecoder sharp(CalibrateFeatureDecoder(photos, SmallCalibration()));
  std::vector<ImageRGB> crops = SamplePhotoCrops(
      photos, options.crop, options.feature_crops, options.seed + 2);
  const std::vector<ImageRGB> originals = crops;
  BlurCropsRandomly(&crops, options.calibration_blur, options.seed + 2 + 1000);
  int changed = 0;
  for (size_t i = 0; i < crops.size(); ++i)
    changed += crops[i].data != originals[i].data;
  EXPECT_GT(changed, int(crops.size()) * 9 / 10);
  const int bits = options.config.num_bits;
  const auto [mean_error, cov_error] =
      WhitenessError(blurred, crops, bits, options.logit_scale);
  EXPECT_LT(mean_error, 1e-3);
  EXPECT_LT(cov_error, 1e-3);
  const auto [sharp_mean_error, sharp_cov_error] =
      WhitenessError(sharp, crops, bits, options.logit_scale);
  EXPECT_GT(std::max(sharp_mean_error, sharp_cov_error), 0.05);
  // Sigma 0 leaves every crop as it was; out-of-range sigmas are refused.
  std::vector<ImageRGB> untouched = originals;
  BlurCropsRandomly(&untouched, 0.0, 7);
  for (size_t i = 0; i < untouched.size(); ++i)
    EXPECT_EQ(untouched[i].data, originals[i].data);
  EXPECT_THROW(BlurCropsRandomly(&untouched, -1.0, 7), Error);
  EXPECT_THROW(BlurCropsRandomly(&untouched, std::nan(""), 7), Error);
}

TEST(FeatureDecoderCalibrationTest, DeterministicForASeed) {
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  FeatureCalibrationOptions options = SmallCalibration();
  const std::string a = SerializeNetworkFile(
      FeatureNetToFile(*CalibrateFeatureDecoder(photos, options)));
  const std::string b = SerializeNetworkFile(
      FeatureNetToFile(*CalibrateFeatureDecoder(photos, options)));
  EXPECT_EQ(a, b);
  options.seed += 1;
  const std::string c = SerializeNetworkFile(
      FeatureNetToFile(*CalibrateFeatureDecoder(photos, options)));
  EXPECT_NE(a, c);
}

TEST(FeatureDecoderCalibrationTest, RefusesTooFewCropsAndTooManyBits) {
  const std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  FeatureCalibrationOptions options = SmallCalibration();
  options.feature_crops = options.config.channels;
  EXPECT_THROW(CalibrateFeatureDecoder(photos, options), Error);
  options = SmallCalibration();
  options.config.num_bits = options.config.channels + 1;
  EXPECT_THROW(CalibrateFeatureDecoder(photos, options), Error);
  options = SmallCalibration();
  options.crop = 100000;
  EXPECT_THROW(CalibrateFeatureDecoder(photos, options), Error);
}

class FeatureDecoderFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("watergs_feature_decoder_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

TEST_F(FeatureDecoderFileTest, RoundTripAndRefusals) {
  FeatureDecoderConfig config{8, 12, 2, 3};
  auto net = RandomNet(config, 3);
  const ImageRGB image = RandomImage(20, 14, 9);
  const std::vector<float> want =
      FeatureDecoder(RandomNet(config, 3)).Logits(image);
  const NetworkFile file = FeatureNetToFile(*net);
  WriteNetworkFile(Path("d.bin"), file);
  std::unique_ptr<BitDecoder> loaded =
      LoadBitDecoder(Path("d.bin"), Device::kCpu);
  EXPECT_EQ(loaded->NumBits(), 8);
  EXPECT_EQ(loaded->Logits(image), want);
  EXPECT_THROW(LoadBitDecoder(Path("d.bin"), Device::kCpu, 48), Error);
  // The high-pass front end travels in the file (and only when set).
  FeatureDecoderConfig residual_config = config;
  residual_config.highpass = 2;
  FeatureDecoder residual(RandomNet(residual_config, 3));
  EXPECT_EQ(FeatureNetToFile(*net).meta.size() + 1,
            FeatureNetToFile(residual.net()).meta.size());
  WriteNetworkFile(Path("r.bin"), FeatureNetToFile(residual.net()));
  const std::vector<float> residual_logits = residual.Logits(image);
  EXPECT_NE(residual_logits, want);
  EXPECT_EQ(LoadBitDecoder(Path("r.bin"), Device::kCpu)->Logits(image),
            residual_logits);
  // The HiDDeN loader names the kind it found.
  try {
    Decoder::Load(Path("d.bin"));
    ADD_FAILURE() << "HiDDeN loader accepted a feature decoder";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("feature-decoder"), std::string::npos);
  }
  auto refuses = [&](NetworkFile f, const std::string& what) {
    WriteNetworkFile(Path("bad.bin"), f);
    try {
      LoadBitDecoder(Path("bad.bin"), Device::kCpu);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("bad.bin"), std::string::npos) << message;
      EXPECT_NE(message.find(what), std::string::npos) << message;
    }
  };
  NetworkFile f = file;
  f.tensors[2].values[5] = std::nanf("");
  refuses(f, "NaN");
  f = file;
  f.tensors.pop_back();
  refuses(f, "tensors");
  f = file;
  f.tensors[0].shape[1] = 4;
  f.tensors[0].values.resize(size_t(12) * 4 * 3 * 3);
  refuses(f, "wrong shape");
  f = file;
  for (auto& m : f.meta)
    if (m.first == "design") m.second = 2;
  refuses(f, "design 2");
  f = file;
  for (auto& m : f.meta)
    if (m.first == "kernel") m.second = 4;
  refuses(f, "kernel 4");
  // A too-small image is an error, not a crash.
  FeatureDecoder small(RandomNet(config, 3));
  EXPECT_THROW(small.Logits(RandomImage(1, 1, 1)), Error);
}

// Steerable: a held-out crop (a photo the calibration did not see) takes a
// random 16-bit message with a small pixel change; balanced: on unmarked
// held-out crops the bits are near fair.
TEST(FeatureDecoderCalibrationTest, SteerableAndBalancedOnHeldOutPhotos) {
  std::vector<cv::Mat> photos = LoadPhotoFolder(kPhotos);
  const std::vector<cv::Mat> held_out(photos.end() - 2, photos.end());
  photos.resize(photos.size() - 2);
  FeatureCalibrationOptions options = SmallCalibration();
  options.whiten_floor = 1e-5;
  options.logit_scale = 4.0;
  FeatureDecoder decoder(CalibrateFeatureDecoder(photos, options));
  std::mt19937 rng(11);
  Bits target(16);
  for (auto& b : target) b = rng() & 1;
  const std::vector<ImageRGB> crops = SamplePhotoCrops(held_out, 64, 200, 3);
  for (int i = 0; i < 2; ++i) {
    const SteerResult r =
        SteerPixels(decoder, crops[i], target, 300, 0.002, 0.5);
    EXPECT_EQ(r.bit_errors, 0) << i;
    EXPECT_GT(r.psnr, 25.0) << i;
  }
  const DecoderBalance balance = MeasureBalance(decoder, crops, target);
  EXPECT_EQ(balance.false_positives, 0);
  EXPECT_GT(balance.ones_fraction, 0.35);
  EXPECT_LT(balance.ones_fraction, 0.65);
}

}  // namespace
}  // namespace watergs
