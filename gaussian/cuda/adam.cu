// CUDA kernels of the Adam optimiser (see adam_kernels.h). AdamValue is
// gaussian/adam.cc's AdamUpdate for one value, and ShBasis/UnitDirection are
// sh.h's in double; all arithmetic goes through the *_rn intrinsics in the
// CPU code's order, so nvcc fuses no multiply-add and the device result is
// fixed by the source alone. (GCC may fuse some on the CPU, -ffp-contract=
// fast being its C++ default, so the two agree to float rounding.)
#include <cfloat>

#include "gaussian/cuda/adam_kernels.h"

namespace watergs {
namespace cuda_adam {
namespace {

constexpr int kThreads = 256;
// Gradients beyond this are clamped so that g * g stays finite in float.
constexpr float kMaxGradMagnitude = 1e18f;

// Returns the number of rejected values (0-2) as AdamUpdate counts them.
__device__ __forceinline__ unsigned AdamValue(const AdamConstants& k, float raw,
                                              float* m, float* v, float* p) {
  const bool finite_grad = fabsf(raw) <= FLT_MAX;  // NaN: false
  const float g = finite_grad
                      ? fminf(fmaxf(raw, -kMaxGradMagnitude), kMaxGradMagnitude)
                      : 0.f;
  const float new_m = __fadd_rn(*m, __fmul_rn(k.w1, __fsub_rn(g, *m)));
  const float new_v =
      __fadd_rn(__fmul_rn(*v, k.beta2), __fmul_rn(__fmul_rn(k.w2, g), g));
  const float denom =
      __fadd_rn(__fdiv_rn(__fsqrt_rn(new_v), k.bias2_sqrt), k.eps);
  const float new_p =
      __fsub_rn(*p, __fmul_rn(k.step_size, __fdiv_rn(new_m, denom)));
  const bool ok = fabsf(new_p) <= FLT_MAX && new_v <= FLT_MAX;
  if (ok) {
    *m = new_m;
    *v = new_v;
    *p = new_p;
  }
  return (finite_grad ? 0u : 1u) + (ok ? 0u : 1u);
}

__global__ void AdamDenseKernel(AdamConstants k, const float* grad, float* m,
                                float* v, float* p, size_t n, int stride,
                                const uint8_t* mask,
                                unsigned long long* rejected) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= n * stride) return;
  if (mask && !mask[j / stride]) return;
  const unsigned bad = AdamValue(k, grad[j], &m[j], &v[j], &p[j]);
  if (bad) atomicAdd(rejected, static_cast<unsigned long long>(bad));
}

__device__ __forceinline__ double Mul(double a, double b) {
  return __dmul_rn(a, b);
}
__device__ __forceinline__ double Add(double a, double b) {
  return __dadd_rn(a, b);
}
__device__ __forceinline__ double Sub(double a, double b) {
  return __dsub_rn(a, b);
}

// sh.h's ShBasis<double> at unit (x, y, z), degree 0-3, same products in the
// same order; c holds kShC0, kShC1, kShC2[5], kShC3[7].
__device__ void ShBasis(int degree, double x, double y, double z,
                        const ShConstants& c, double* b) {
  b[0] = c.c0;
  if (degree < 1) return;
  b[1] = Mul(-c.c1, y);
  b[2] = Mul(c.c1, z);
  b[3] = Mul(-c.c1, x);
  if (degree < 2) return;
  const double xx = Mul(x, x), yy = Mul(y, y), zz = Mul(z, z);
  b[4] = Mul(Mul(c.c2[0], x), y);
  b[5] = Mul(Mul(c.c2[1], y), z);
  b[6] = Mul(c.c2[2], Sub(Sub(Mul(2.0, zz), xx), yy));
  b[7] = Mul(Mul(c.c2[3], x), z);
  b[8] = Mul(c.c2[4], Sub(xx, yy));
  if (degree < 3) return;
  b[9] = Mul(Mul(c.c3[0], y), Sub(Mul(3.0, xx), yy));
  b[10] = Mul(Mul(Mul(c.c3[1], x), y), z);
  b[11] = Mul(Mul(c.c3[2], y), Sub(Sub(Mul(4.0, zz), xx), yy));
  b[12] =
      Mul(Mul(c.c3[3], z), Sub(Sub(Mul(2.0, zz), Mul(3.0, xx)), Mul(3.0, yy)));
  b[13] = Mul(Mul(c.c3[4], x), Sub(Sub(Mul(4.0, zz), xx), yy));
  b[14] = Mul(Mul(c.c3[5], z), Sub(xx, yy));
  b[15] = Mul(Mul(c.c3[6], x), Sub(xx, Mul(3.0, yy)));
}

// One thread per Gaussian: the SH basis of its view direction (sh.cc's
// UnitDirection: +z for a zero direction), then each value's gradient
// basis[k] * dL/dcolour[c] rounded to float, as ShCoefficientGradients.
__global__ void AdamFactoredShKernel(AdamConstants k, ShConstants sh,
                                     const float* color_grad,
                                     const float* view_dir, int degree, bool dc,
                                     float* m, float* v, float* p, size_t n,
                                     int stride, const uint8_t* mask,
                                     unsigned long long* rejected) {
  const size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  if (mask && !mask[i]) return;
  const double d0 = view_dir[3 * i], d1 = view_dir[3 * i + 1],
               d2 = view_dir[3 * i + 2];
  const double norm =
      __dsqrt_rn(Add(Add(Mul(d0, d0), Mul(d1, d1)), Mul(d2, d2)));
  const bool ok = norm > 1e-30;
  const double x = ok ? __ddiv_rn(d0, norm) : 0.0;
  const double y = ok ? __ddiv_rn(d1, norm) : 0.0;
  const double z = ok ? __ddiv_rn(d2, norm) : 1.0;
  double basis[16];
  ShBasis(degree, x, y, z, sh, basis);
  const int coefficients = (degree + 1) * (degree + 1);
  const float* gc = color_grad + 3 * i;
  unsigned bad = 0;
  for (int q = 0; q < stride; ++q) {
    const int coefficient = dc ? 0 : q / 3 + 1;
    const float g =
        coefficient < coefficients
            ? static_cast<float>(
                  Mul(basis[coefficient], static_cast<double>(gc[q % 3])))
            : 0.f;
    const size_t j = i * stride + q;
    bad += AdamValue(k, g, &m[j], &v[j], &p[j]);
  }
  if (bad) atomicAdd(rejected, static_cast<unsigned long long>(bad));
}

__global__ void GatherRowsKernel(const float* in, const int64_t* index,
                                 size_t n_out, int stride, float* out) {
  const size_t j = blockIdx.x * size_t(blockDim.x) + threadIdx.x;
  if (j >= n_out * stride) return;
  const int64_t from = index[j / stride];
  out[j] = from < 0 ? 0.f : in[size_t(from) * stride + j % stride];
}

unsigned Blocks(size_t count) {
  return static_cast<unsigned>((count + kThreads - 1) / kThreads);
}

}  // namespace

cudaError_t LaunchAdamDense(const AdamConstants& k, const float* grad, float* m,
                            float* v, float* p, size_t n, int stride,
                            const uint8_t* mask, unsigned long long* rejected,
                            cudaStream_t stream) {
  if (n == 0 || stride == 0) return cudaSuccess;
  AdamDenseKernel<<<Blocks(n * stride), kThreads, 0, stream>>>(
      k, grad, m, v, p, n, stride, mask, rejected);
  return cudaGetLastError();
}

cudaError_t LaunchAdamFactoredSh(const AdamConstants& k, const ShConstants& sh,
                                 const float* color_grad, const float* view_dir,
                                 int degree, bool dc, float* m, float* v,
                                 float* p, size_t n, int stride,
                                 const uint8_t* mask,
                                 unsigned long long* rejected,
                                 cudaStream_t stream) {
  if (n == 0 || stride == 0) return cudaSuccess;
  AdamFactoredShKernel<<<Blocks(n), kThreads, 0, stream>>>(
      k, sh, color_grad, view_dir, degree, dc, m, v, p, n, stride, mask,
      rejected);
  return cudaGetLastError();
}

cudaError_t LaunchGatherRows(const float* in, const int64_t* index,
                             size_t n_out, int stride, float* out,
                             cudaStream_t stream) {
  if (n_out == 0 || stride == 0) return cudaSuccess;
  GatherRowsKernel<<<Blocks(n_out * stride), kThreads, 0, stream>>>(
      in, index, n_out, stride, out);
  return cudaGetLastError();
}

}  // namespace cuda_adam
}  // namespace watergs
