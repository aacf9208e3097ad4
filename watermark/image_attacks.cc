// Attacks on rendered images (see image_attacks.h).
#include "watermark/image_attacks.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "gaussian/util/error.h"
#include "gaussian/util/text_util.h"
#include "watermark/image_noise.h"
#include "watermark/network_image.h"

namespace watergs {
namespace {

double ParseValue(const std::string& text, const std::string& value) {
  const std::optional<double> parsed = ParseFiniteDouble(value);
  if (!parsed) {
    Fail("--image_attack: '" + Printable(text) + "': '" + Printable(value) +
         "' is not a number");
  }
  return *parsed;
}

ImageRGB Jpeg(int quality, const ImageRGB& image) {
  // The decoder-training JPEG layer works on [-1, 1] NCHW tensors.
  Tensor tensor;
  ImageToTensor(image, true, &tensor);
  NoiseStrengths strengths;
  strengths.jpeg_quality = quality;
  ImageNoise noise(strengths);
  Tensor compressed;
  std::mt19937 unused_rng(0);
  noise.Forward(NoiseKind::kJpeg, tensor, tensor, &compressed, &unused_rng);
  return TensorToImage(compressed);
}

ImageRGB Resize(double factor, const ImageRGB& image) {
  const int width = std::max(1, int(std::lround(factor * image.width)));
  const int height = std::max(1, int(std::lround(factor * image.height)));
  return ResizeTo(image, width, height);
}

}  // namespace

ImageRGB ResizeTo(const ImageRGB& image, int width, int height) {
  if (width <= 0 || height <= 0) Fail("resize to an empty image");
  if (width == image.width && height == image.height) return image;
  const cv::Mat in(image.height, image.width, CV_32FC3,
                   const_cast<float*>(image.data.data()));
  ImageRGB out(width, height);
  cv::Mat resized(height, width, CV_32FC3, out.data.data());
  const bool shrink = width < image.width || height < image.height;
  cv::resize(in, resized, cv::Size(width, height), 0, 0,
             shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  for (float& v : out.data) v = std::clamp(v, 0.f, 1.f);
  return out;
}

ImageRGB AttackAsDecoded(const ImageAttackSpec& spec, const ImageRGB& render) {
  const ImageRGB attacked = ApplyImageAttack(spec, render);
  if (spec.kind != ImageAttackKind::kResize) return attacked;
  return ResizeTo(attacked, render.width, render.height);
}

namespace {

ImageRGB Crop(double fraction, const ImageRGB& image) {
  const int width = std::max(1, int(std::lround(fraction * image.width)));
  const int height = std::max(1, int(std::lround(fraction * image.height)));
  const int x0 = (image.width - width) / 2, y0 = (image.height - height) / 2;
  ImageRGB out(width, height);
  for (int y = 0; y < height; ++y) {
    std::copy_n(image.At(x0, y0 + y), size_t(width) * 3, out.At(0, y));
  }
  for (float& v : out.data) v = std::clamp(v, 0.f, 1.f);
  return out;
}

}  // namespace

ImageAttackSpec ParseImageAttack(const std::string& text) {
  const size_t colon = text.find(':');
  if (colon == std::string::npos) {
    Fail("--image_attack: '" + Printable(text) +
         "' needs a strength (jpeg:Q, resize:F, crop:F)");
  }
  const std::string name = text.substr(0, colon);
  ImageAttackSpec spec;
  spec.value = ParseValue(text, text.substr(colon + 1));
  if (name == "jpeg") {
    spec.kind = ImageAttackKind::kJpeg;
    if (spec.value != std::round(spec.value) || spec.value < 1 ||
        spec.value > 100) {
      Fail("--image_attack: '" + Printable(text) +
           "': quality must be an integer 1-100");
    }
  } else if (name == "resize") {
    spec.kind = ImageAttackKind::kResize;
    if (!(spec.value > 0 && spec.value <= 4)) {
      Fail("--image_attack: '" + Printable(text) +
           "': factor must be in (0, 4]");
    }
  } else if (name == "crop") {
    spec.kind = ImageAttackKind::kCrop;
    if (!(spec.value > 0 && spec.value <= 1)) {
      Fail("--image_attack: '" + Printable(text) +
           "': fraction must be in (0, 1]");
    }
  } else {
    Fail("--image_attack: unknown attack '" + Printable(text) +
         "' (jpeg:Q, resize:F, crop:F)");
  }
  return spec;
}

std::vector<ImageAttackSpec> ParseImageAttackList(const std::string& text) {
  std::vector<ImageAttackSpec> specs;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    specs.push_back(ParseImageAttack(item));
  }
  if (specs.empty()) Fail("--image_attack: empty list");
  return specs;
}

std::string ToString(const ImageAttackSpec& spec) {
  std::ostringstream out;
  switch (spec.kind) {
    case ImageAttackKind::kJpeg:
      out << "jpeg:";
      break;
    case ImageAttackKind::kResize:
      out << "resize:";
      break;
    case ImageAttackKind::kCrop:
      out << "crop:";
      break;
  }
  out << spec.value;
  return out.str();
}

ImageRGB ApplyImageAttack(const ImageAttackSpec& spec, const ImageRGB& image) {
  if (image.width <= 0 || image.height <= 0) {
    Fail("--image_attack: empty image");
  }
  switch (spec.kind) {
    case ImageAttackKind::kJpeg:
      return Jpeg(int(spec.value), image);
    case ImageAttackKind::kResize:
      return Resize(spec.value, image);
    case ImageAttackKind::kCrop:
      return Crop(spec.value, image);
  }
  return image;
}

}  // namespace watergs
