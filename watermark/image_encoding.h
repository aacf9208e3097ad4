// HiDDeN's encoder applied to whole images: the first WATER-GS baseline
// ("HiDDeN + 3DGS", paper Sec. 5) watermarks a scene's training images with
// it, trains 3DGS on them and tries to read the message from the renders.
#pragma once

#include "gaussian/image.h"
#include "watermark/hidden_model.h"
#include "watermark/message.h"

namespace watergs {

// The watermarked image of `cover` (values in [0, 1]) carrying `message`
// (model.config.num_bits bits): the encoder's output at the cover's size
// (it is fully convolutional), clamped to [0, 1]. Error when the model has
// no encoder or the message length differs.
ImageRGB EncodeImage(HiddenModel& model, const ImageRGB& cover,
                     const Bits& message);

}  // namespace watergs
