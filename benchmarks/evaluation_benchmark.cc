// Evaluation benchmark: cost of the metrics and attacks `watergs eval` runs:
// MS-SSIM and LPIPS-VGG feature extraction (random weights: the cost does not
// depend on them) at 240x180 and 480x360, each model attack on a random
// degree-3 model of 100k Gaussians, and each image attack at 480x360.
// Medians of repeated runs.
//
// Usage: evaluation_benchmark [repeats=5]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "benchmarks/benchmark_util.h"
#include "distortion/file_attacks.h"
#include "watermark/image_attacks.h"
#include "watermark/image_quality.h"
#include "watermark/lpips.h"

namespace {

using watergs::bench::MedianSeconds;

using Clock = std::chrono::steady_clock;

watergs::ImageRGB RandomImage(int w, int h, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  watergs::ImageRGB image(w, h);
  for (float& v : image.data) v = unit(rng);
  return image;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace watergs;
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  std::printf("evaluation_benchmark: medians of %d runs\n", repeats);
  auto lpips = Lpips::WithRandomWeights(1);
  for (const auto& [w, h] : {std::pair{240, 180}, std::pair{480, 360}}) {
    const ImageRGB a = RandomImage(w, h, 1), b = RandomImage(w, h, 2);
    const double ms_ssim = MedianSeconds(repeats, [&] { MsSsim(a, b); });
    const double lpips_s = MedianSeconds(repeats, [&] { lpips->Extract(a); });
    std::printf("  %dx%d: MS-SSIM %.3f s, LPIPS features %.3f s per image\n", w,
                h, ms_ssim, lpips_s);
  }

  std::mt19937_64 rng(2);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianModel model;
  model.sh_degree = 3;
  model.Resize(100000);
  for (std::vector<float>* array :
       {&model.means, &model.log_scales, &model.quats, &model.opacity_logits,
        &model.sh_dc, &model.sh_rest}) {
    for (float& v : *array) v = u(rng);
  }
  std::printf("  model attacks on %zu Gaussians (SH degree 3):\n",
              model.size());
  for (const ModelAttackSpec& spec : ParseModelAttackList(
           "gn:0.01,dropout:0.1,crop:0.1,sh0,fp16,quant:8,shuffle,"
           "similarity:30,0.1,-0.2,0.3,1.5,1,1,1,prune:0.05")) {
    GaussianModel out;
    std::vector<uint32_t> source;
    const double s = MedianSeconds(
        repeats, [&] { ApplyModelAttack(spec, model, rng, &out, &source); });
    std::printf("    %-40s %.4f s\n", ToString(spec).c_str(), s);
  }
  const ImageRGB frame = RandomImage(480, 360, 3);
  std::printf("  image attacks at 480x360:\n");
  for (const ImageAttackSpec& spec :
       ParseImageAttackList("jpeg:75,jpeg:50,resize:0.5,crop:0.5")) {
    const double s =
        MedianSeconds(repeats, [&] { ApplyImageAttack(spec, frame); });
    std::printf("    %-12s %.5f s\n", ToString(spec).c_str(), s);
  }
  return 0;
}
