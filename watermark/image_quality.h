// Image-quality metrics for evaluation beyond the training losses
// (gaussian/loss.h has PSNR and Inria's SSIM): multi-scale SSIM.
//
// MS-SSIM follows Wang, Simoncelli and Bovik (2003): at each of M scales an
// 11x11 Gaussian window (sigma 1.5) is applied as a "valid" filter (no
// padding) to each channel, C1 = 0.01^2, C2 = 0.03^2 (data range 1); scales
// 1..M-1 contribute the mean contrast-structure term cs_j and scale M the
// mean SSIM; between scales the image is averaged over 2x2 blocks (an odd
// last row/column is dropped). MS-SSIM = prod_j cs_j^w_j * ssim_M^w_M per
// channel (negative terms clamped to 0 so fractional powers stay real), then
// the mean over channels. Weights 0.0448, 0.2856, 0.3001, 0.2363, 0.1333.
// M = 5 needs both sides >= 176 pixels (11 << 4). Smaller images use the
// largest M whose coarsest scale still holds a window, with the first M
// weights renormalised to sum 1 (five scales use the published weights as
// they are); images under 11 pixels have no MS-SSIM.
#pragma once

#include "gaussian/image.h"

namespace watergs {

// The standard five-scale weights.
inline constexpr double kMsSsimWeights[5] = {0.0448, 0.2856, 0.3001, 0.2363,
                                             0.1333};

// Number of scales MS-SSIM uses for a width x height image (0 to 5).
int MsSsimScales(int width, int height);

struct MsSsimResult {
  // MS-SSIM in [0, 1]; NaN when scales == 0.
  double value = 0;
  // Scales used (5 unless the image is small).
  int scales = 0;
};

// MS-SSIM of two images of equal size (values clamped to [0, 1] first);
// throws Error on a size mismatch.
MsSsimResult MsSsim(const ImageRGB& a, const ImageRGB& b);

}  // namespace watergs
