// TrainDecoder with options.device = kCuda (watergs train_decoder --device
// cuda): a few steps from a fixed seed take the CPU run's trajectory and
// reach its weights, a checkpoint written on the GPU holds the device's
// weights and Adam state and resumes on the CPU, and where CUDA is unusable
// the option fails with one line saying why (that test and the CPU resume
// test run everywhere; the GPU ones skip without a GPU).
//
// Tolerances (GPU against CPU, same seed, tiny model, lr 1e-3):
// - Step 0 starts from identical weights: BCE and PSNR within 1e-3 relative,
//   as the one-step parity test in cuda_decoder_test.cc.
// - Later steps start from weights that differ by a fraction of one Adam
//   update (below): BCE and PSNR within 1e-2 relative, bit accuracy within
//   2 of the 24 bits a step decodes (a logit near 0 may change sign).
// - Weights: per trainable tensor, |update_gpu - update_cpu| <= 0.2 *
//   |update_cpu| (Euclidean norms; update = final - initial). Adam's early
//   steps are ~lr * sign(g): gradients agree to ~1e-3 of the tensor's
//   largest one, so only elements whose gradient is within that noise can
//   step the other way. For gradients spread like a Gaussian with the
//   largest at ~5 sigma that is ~0.3% of the elements, moving up to 2 lr
//   per step apart: ~2 * sqrt(0.003) = 0.11 of the update norm if every
//   one of them flipped; 0.2 leaves room for heavier tails. Measured on the
//   CPU with this setup: two runs differ by < 2e-4 of the update norm, and
//   3 steps against 6 by 0.33-0.57, so 0.2 still catches a lost step or
//   update. Conv biases
//   ahead of a training-mode BatchNorm have zero gradient (BN removes the
//   mean), so both sides hold rounding noise there: skipped.
// - Running statistics and Adam moments (averages of g and g^2: no sign
//   effect): within 2e-2 of the largest magnitude (the weights they come
//   from differ by <1% of their size after a few steps).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "gaussian/device.h"
#include "gaussian/util/error.h"
#include "tests/common/cuda_test.h"
#include "watermark/decoder_training.h"
#include "watermark/hidden_model.h"
#include "watermark/network_file.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// Seed of every run (TrainDecoder initialises the model from it).
constexpr uint32_t kSeed = 11;

const std::string kPhotos =
    std::string(WATERGS_SOURCE_DIR) + "/tests/data/photos";

// A fresh folder under the system temp dir, removed with the object.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& tag)
      : path_(fs::temp_directory_path() / ("watergs_cuda_dec_train_" + tag +
                                           "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() { fs::remove_all(path_); }
  // path/name as a string.
  std::string operator/(const std::string& name) const {
    return (path_ / name).string();
  }

 private:
  fs::path path_;
};

// Steps seen through on_step and their figures.
struct Trajectory {
  std::vector<int64_t> steps;
  std::vector<StepResult> results;
};

// Tiny model, 16 px crops, 3 crops per step, 3 steps per epoch, every
// noise layer in the draw (with kSeed and tests/data/photos, steps 0-5 draw
// crop, identity, resize, resize, blur, crop: device and host layers),
// checkpoints only at epoch ends; records the trajectory into *trajectory.
DecoderTrainingOptions TinyRun(const std::string& output, Device device,
                               int epochs, Trajectory* trajectory) {
  DecoderTrainingOptions options;
  options.image_path = kPhotos;
  options.output_path = output;
  options.config.num_bits = 8;
  options.config.channels = 8;
  options.config.encoder_blocks = 2;
  options.config.decoder_blocks = 2;
  options.crop = 16;
  options.batch_size = 3;
  options.steps_per_epoch = 3;
  options.epochs = epochs;
  options.checkpoint_every = 0;
  options.noise = {NoiseKind::kIdentity, NoiseKind::kCrop, NoiseKind::kDropout,
                   NoiseKind::kResize,   NoiseKind::kBlur, NoiseKind::kJpeg};
  options.seed = kSeed;
  options.device = device;
  options.resume = true;
  options.on_step = [trajectory](int64_t step, const StepResult& result) {
    trajectory->steps.push_back(step);
    trajectory->results.push_back(result);
  };
  return options;
}

double Norm(const std::vector<float>& v) {
  double sum = 0.0;
  for (float x : v) sum += double(x) * x;
  return std::sqrt(sum);
}

double MaxAbs(const std::vector<float>& v) {
  double scale = 0.0;
  for (float x : v) scale = std::max(scale, double(std::abs(x)));
  return scale;
}

// b - a.
std::vector<float> Minus(const std::vector<float>& b,
                         const std::vector<float>& a) {
  std::vector<float> d(b.size());
  for (size_t i = 0; i < b.size(); ++i) d[i] = b[i] - a[i];
  return d;
}

// Element-wise within `relative` of the largest |cpu| value.
void ExpectCloseToMax(const std::vector<float>& gpu,
                      const std::vector<float>& cpu, double relative,
                      const std::string& what) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  const double bound = relative * MaxAbs(cpu) + 1e-30;
  double worst = 0.0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    ASSERT_TRUE(std::isfinite(gpu[i])) << what << " [" << i << "]";
    worst = std::max(worst, std::abs(double(gpu[i]) - cpu[i]));
  }
  EXPECT_LE(worst, bound) << what;
}

// Conv biases ahead of a training-mode BatchNorm (zero gradient).
bool BiasBeforeBatchNorm(const Parameter& p) {
  return p.name.find(".conv.bias") != std::string::npos;
}

// Weights (as in the header's tolerances) of a GPU and a CPU run that took
// the same steps from the same initial model.
void ExpectSameUpdates(HiddenModel& gpu, HiddenModel& cpu) {
  HiddenModel initial(cpu.config, true, kSeed);
  const std::vector<Parameter*> g = gpu.AllParameters();
  const std::vector<Parameter*> c = cpu.AllParameters();
  const std::vector<Parameter*> w0 = initial.AllParameters();
  ASSERT_EQ(g.size(), c.size());
  for (size_t k = 0; k < c.size(); ++k) {
    if (!c[k]->trainable) {
      ExpectCloseToMax(g[k]->value, c[k]->value, 2e-2, c[k]->name);
      continue;
    }
    if (BiasBeforeBatchNorm(*c[k])) continue;
    const std::vector<float> cpu_update = Minus(c[k]->value, w0[k]->value);
    const double moved = Norm(cpu_update);
    ASSERT_GT(moved, 0.0) << c[k]->name << " did not train";
    const double apart =
        Norm(Minus(Minus(g[k]->value, w0[k]->value), cpu_update));
    EXPECT_LE(apart, 0.2 * moved) << c[k]->name;
  }
}

// Step figures of a GPU and a CPU run (tolerances in the header).
void ExpectSameTrajectory(const Trajectory& gpu, const Trajectory& cpu) {
  ASSERT_EQ(gpu.steps, cpu.steps);
  for (size_t i = 0; i < cpu.results.size(); ++i) {
    const StepResult& g = gpu.results[i];
    const StepResult& c = cpu.results[i];
    const double relative = cpu.steps[i] == 0 ? 1e-3 : 1e-2;
    EXPECT_NEAR(g.bce, c.bce, relative * c.bce) << "step " << cpu.steps[i];
    EXPECT_NEAR(g.psnr, c.psnr, relative * c.psnr) << "step " << cpu.steps[i];
    EXPECT_NEAR(g.accuracy, c.accuracy, 2.0 / 24.0) << "step " << cpu.steps[i];
  }
}

std::vector<int64_t> Range(int64_t begin, int64_t end) {
  std::vector<int64_t> steps;
  for (int64_t s = begin; s < end; ++s) steps.push_back(s);
  return steps;
}

// The steps of `run` from index `first` on.
Trajectory Tail(const Trajectory& run, size_t first) {
  Trajectory tail;
  tail.steps.assign(run.steps.begin() + first, run.steps.end());
  tail.results.assign(run.results.begin() + first, run.results.end());
  return tail;
}

// Runs without a GPU too: the device is checked before any photo is read.
TEST(CudaDecoderTrainingTest, CudaWithoutUsableGpuFailsWithOneLineSayingWhy) {
  std::string why;
  if (CudaAvailable(&why)) GTEST_SKIP() << "a GPU is visible here";
  ScratchDir dir("refused");
  Trajectory trajectory;
  DecoderTrainingOptions options =
      TinyRun(dir / "decoder.bin", Device::kCuda, 1, &trajectory);
  options.image_path = dir / "no_such_folder";
  try {
    TrainDecoder(options);
    ADD_FAILURE() << "--device cuda was accepted without a usable GPU";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("train_decoder --device cuda: ", 0), 0u) << message;
    EXPECT_FALSE(why.empty());
    EXPECT_NE(message.find(why), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
#ifdef WATERGS_WITH_CUDA
    EXPECT_NE(message.find("no CUDA device"), std::string::npos) << message;
#else
    EXPECT_NE(message.find("without the CUDA backend"), std::string::npos)
        << message;
#endif
  }
  EXPECT_TRUE(trajectory.steps.empty());
  EXPECT_FALSE(fs::exists(dir / "decoder.bin"));
  EXPECT_FALSE(fs::exists(dir / "decoder.bin.ckpt"));
}

// The CPU reference of the cross-device resume test below: 3 steps, a
// checkpoint, 3 more after a resume, against 6 steps straight. The CPU path
// is not bit-reproducible between runs in one process (two straight runs
// already differ in the last float bits from the first update on, and
// Adam turns the zero-gradient conv biases' rounding noise into +-lr
// steps), so the runs are compared at the GPU tests' tolerances.
TEST(CudaDecoderTrainingTest, CpuResumeContinuesAStraightRun) {
  ScratchDir dir("cpu_resume");
  Trajectory straight, first, second;
  TrainDecoder(TinyRun(dir / "straight.bin", Device::kCpu, 2, &straight));
  TrainDecoder(TinyRun(dir / "split.bin", Device::kCpu, 1, &first));
  TrainDecoder(TinyRun(dir / "split.bin", Device::kCpu, 2, &second));
  EXPECT_EQ(straight.steps, Range(0, 6));
  EXPECT_EQ(first.steps, Range(0, 3));
  ASSERT_EQ(second.steps, Range(3, 6));
  ExpectSameTrajectory(second, Tail(straight, 3));
  auto split = LoadHiddenModel(dir / "split.bin", true);
  auto reference = LoadHiddenModel(dir / "straight.bin", true);
  ExpectSameUpdates(*split, *reference);
}

TEST(CudaDecoderTrainingTest, GpuStepsFollowTheCpuTrajectory) {
  WATERGS_REQUIRE_CUDA();
  ScratchDir dir("trajectory");
  Trajectory cpu, gpu;
  TrainDecoder(TinyRun(dir / "cpu.bin", Device::kCpu, 2, &cpu));
  TrainDecoder(TinyRun(dir / "gpu.bin", Device::kCuda, 2, &gpu));
  ExpectSameTrajectory(gpu, cpu);
  auto cpu_model = LoadHiddenModel(dir / "cpu.bin", true);
  auto gpu_model = LoadHiddenModel(dir / "gpu.bin", true);
  ExpectSameUpdates(*gpu_model, *cpu_model);
}

// Weights and Adam moments of a GPU checkpoint against the CPU's.
void ExpectSameCheckpoints(const std::string& gpu_path,
                           const std::string& cpu_path) {
  const NetworkFile gpu = ReadNetworkFile(gpu_path);
  const NetworkFile cpu = ReadNetworkFile(cpu_path);
  EXPECT_EQ(gpu.Meta("step", gpu_path), cpu.Meta("step", cpu_path));
  EXPECT_EQ(gpu.Meta("adam_step", gpu_path), cpu.Meta("adam_step", cpu_path));
  auto gpu_model = HiddenModelFromFile(gpu_path, gpu, true);
  auto cpu_model = HiddenModelFromFile(cpu_path, cpu, true);
  ExpectSameUpdates(*gpu_model, *cpu_model);
  for (const Parameter* p : cpu_model->AllParameters()) {
    if (!p->trainable || BiasBeforeBatchNorm(*p)) continue;
    for (const char* moment : {"adam.m.", "adam.v."}) {
      const TensorRecord* g = gpu.Find(moment + p->name);
      const TensorRecord* c = cpu.Find(moment + p->name);
      ASSERT_TRUE(g && c) << moment << p->name;
      ASSERT_GT(MaxAbs(c->values), 0.0) << moment << p->name;
      ExpectCloseToMax(g->values, c->values, 2e-2, moment + p->name);
    }
  }
}

TEST(CudaDecoderTrainingTest, GpuCheckpointResumesOnTheCpu) {
  WATERGS_REQUIRE_CUDA();
  ScratchDir dir("cross_device");
  Trajectory cpu_first, gpu_first, resumed, reference;
  TrainDecoder(TinyRun(dir / "cpu.bin", Device::kCpu, 1, &cpu_first));
  TrainDecoder(TinyRun(dir / "gpu.bin", Device::kCuda, 1, &gpu_first));
  // The checkpoint holds what the device computed, Adam state included.
  ExpectSameCheckpoints(dir / "gpu.bin.ckpt", dir / "cpu.bin.ckpt");

  // The CPU continues the GPU's run where it stopped and ends where a CPU
  // run of all six steps ends.
  TrainDecoder(TinyRun(dir / "gpu.bin", Device::kCpu, 2, &resumed));
  EXPECT_EQ(resumed.steps, Range(3, 6));
  TrainDecoder(TinyRun(dir / "reference.bin", Device::kCpu, 2, &reference));
  ExpectSameTrajectory(resumed, Tail(reference, 3));
  auto resumed_model = LoadHiddenModel(dir / "gpu.bin", true);
  auto reference_model = LoadHiddenModel(dir / "reference.bin", true);
  ExpectSameUpdates(*resumed_model, *reference_model);
}

}  // namespace
}  // namespace watergs
