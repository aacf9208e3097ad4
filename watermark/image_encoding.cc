// HiDDeN encoder on whole images (see image_encoding.h).
#include "watermark/image_encoding.h"

#include <algorithm>
#include <string>
#include <vector>

#include "gaussian/util/error.h"
#include "watermark/network_image.h"

namespace watergs {

ImageRGB EncodeImage(HiddenModel& model, const ImageRGB& cover,
                     const Bits& message) {
  if (!model.encoder) Fail("encode: the weights have no encoder");
  if (static_cast<int>(message.size()) != model.config.num_bits) {
    Fail("encode: message has " + std::to_string(message.size()) +
         " bits, the encoder writes " + std::to_string(model.config.num_bits));
  }
  Tensor input;
  ImageToTensor(cover, false, &input);
  return TensorToImage(model.encoder->Forward(input, BitSigns(message), false));
}

}  // namespace watergs
