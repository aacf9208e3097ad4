// HiDDeN encoder on whole images (see image_encoding.h).
#include "watermark/image_encoding.h"

#include <algorithm>
#include <string>
#include <vector>

#include "gaussian/error.h"
#include "watermark/tensor.h"

namespace watergs {

ImageRGB EncodeImage(HiddenModel& model, const ImageRGB& cover,
                     const Bits& message) {
  if (!model.encoder) Fail("encode: the weights have no encoder");
  if (static_cast<int>(message.size()) != model.config.num_bits) {
    Fail("encode: message has " + std::to_string(message.size()) +
         " bits, the encoder writes " + std::to_string(model.config.num_bits));
  }
  // The networks' input convention (decoder.cc): [1,3,H,W] = 2 v - 1, and
  // the message as +-1 planes.
  Tensor input(1, 3, cover.height, cover.width);
  const size_t hw = input.PlaneSize();
  for (size_t p = 0; p < hw; ++p)
    for (int c = 0; c < 3; ++c)
      input.data[c * hw + p] = 2.f * cover.data[p * 3 + c] - 1.f;
  std::vector<float> signs(message.size());
  for (size_t i = 0; i < message.size(); ++i)
    signs[i] = message[i] ? 1.f : -1.f;
  const Tensor& watermarked = model.encoder->Forward(input, signs, false);
  ImageRGB out(cover.width, cover.height);
  for (size_t p = 0; p < hw; ++p)
    for (int c = 0; c < 3; ++c)
      out.data[p * 3 + c] =
          std::clamp(0.5f * (watermarked.data[c * hw + p] + 1.f), 0.f, 1.f);
  return out;
}

}  // namespace watergs
