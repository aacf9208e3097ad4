#include "watermark/texture_masking.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace watergs {

std::vector<float> TextureMaskingWeights(const ImageRGB& image, double sigma0) {
  cv::Mat luma(image.height, image.width, CV_32F);
  for (int i = 0; i < image.height * image.width; ++i) {
    const float* p = &image.data[size_t(i) * 3];
    luma.at<float>(i) = 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
  }
  cv::Mat mean, mean_sq;
  cv::boxFilter(luma, mean, CV_32F, cv::Size(7, 7), cv::Point(-1, -1), true,
                cv::BORDER_REFLECT);
  cv::boxFilter(luma.mul(luma), mean_sq, CV_32F, cv::Size(7, 7),
                cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  std::vector<float> weights(size_t(image.height) * image.width);
  double total = 0;
  for (size_t i = 0; i < weights.size(); ++i) {
    const float m = mean.at<float>(int(i)), m2 = mean_sq.at<float>(int(i));
    const double sigma = std::sqrt(std::max(0.f, m2 - m * m));
    weights[i] = float(1 / (1 + sigma / sigma0));
    total += weights[i];
  }
  const float normalise = float(weights.size() / std::max(total, 1e-12));
  for (float& w : weights) w *= normalise;
  return weights;
}

}  // namespace watergs
