// The owner's reference for an image file: the raw model's render sent the
// way the file went (rendered at the file's size, saved as JPEG at the
// file's quality when its quantisation tables are the IJG ones, resized to
// the size it is decoded at), so that the difference reading cancels the
// scene and what was done to it, and leaves the watermark. A plain render
// at the decoded size keeps the scene's JPEG blocks and resampling blur in
// the difference, which the decoder reads as noise.
#pragma once

#include <string>

#include "gaussian/camera.h"
#include "gaussian/image.h"
#include "plugin/photometric_refinement.h"

namespace watergs {

// The IJG quality (1-100) whose scaled luminance table the JPEG file at
// `path` carries (libjpeg's, OpenCV's, most encoders'), or 0: not a JPEG,
// an unreadable header, or another table. Reads the DQT markers only.
int JpegQualityOf(const std::string& path);

// What happened to a suspect image between its render and the decoder.
struct SuspectProcessing {
  // The image's size as loaded, before it was resized for decoding.
  int width = 0, height = 0;
  // JPEG quality it was saved at (0: none known).
  int jpeg_quality = 0;
};

// `render` at `camera` (the size the image is decoded at) as the suspect
// went: rendered at `processing`'s size (the camera scaled to it), through
// JPEG at its quality, then resized back to the camera's size.
ImageRGB RenderLikeSuspect(const CameraRenderer& render,
                           const RenderCamera& camera,
                           const SuspectProcessing& processing);

}  // namespace watergs
