// Launch API of the random-feature decoder's own CUDA kernels
// (feature_kernels.cu): the pieces of FeatureNet (feature_decoder.h) around
// its cuBLAS GEMMs (convolution and projection), with the CPU's formulas.
// Device pointers, NCHW float tensors, default stream; each launcher returns
// cudaGetLastError() for the caller's WATERGS_CUDA_CHECK.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>

namespace watergs {
namespace feature_kernels {

// A width x height HWC patch (rows `pitch` pixels apart, values in [0, 1])
// -> pooled [3, height / p, width / p]: each p x p block's mean of the
// network input 2 v - 1, summed row by row as AvgPoolForward does (columns
// and rows beyond a multiple of p are dropped).
cudaError_t ImageToPooledInput(const float* hwc, int width, int height,
                               int pitch, int p, float* pooled);
// pooled [in, ph, pw] -> cols [in * k * k + 1, ph * pw]: row (c, dy, dx)
// holds the input at (y + dy - k / 2, x + dx - k / 2) of each output pixel
// (0 outside: zero padding), the last row 1 (the bias), so that the k x k
// convolution is one GEMM with the [out, in * k * k + 1] weights.
cudaError_t Im2Col(const float* pooled, int in, int ph, int pw, int k,
                   float* cols);
// dcols [in * k * k, ph * pw] -> dpooled [in, ph, pw]: Im2Col's adjoint,
// each input value's k * k terms added in a fixed order.
cudaError_t Col2Im(const float* dcols, int in, int ph, int pw, int k,
                   float* dpooled);
// conv [channels, hw] -> features [channels]: the mean of max(y, 0) per
// channel, summed in double (ReluGlobalAvgPoolForward).
cudaError_t ReluGlobalAvgPool(const float* conv, int channels, size_t hw,
                              float* features);
// dfeatures [channels] -> dconv [channels, hw] = dfeatures / hw where the
// convolution's output is > 0, else 0 (ReluGlobalAvgPoolBackward).
cudaError_t ReluGlobalAvgPoolBackward(const float* dfeatures, const float* conv,
                                      int channels, size_t hw, float* dconv);
// dpooled [3, height / p, width / p] -> the width x height HWC patch's
// gradient: 2 dpooled / p^2 over each block (input = 2 image - 1), 0 on the
// dropped border; written, or added when `accumulate`.
cudaError_t PooledGradientToImage(const float* dpooled, int width, int height,
                                  int pitch, int p, bool accumulate,
                                  float* dhwc);

}  // namespace feature_kernels
}  // namespace watergs
