// COLMAP 3.8's camera models (ids 0-10), mirrored so that swapping in
// colmap/base/camera_models.h later is mechanical: same ids, names, parameter
// order and projection formulas. Each model's WorldToImage / ImageToWorld is
// written once as a template and runs on double and on ceres::Jet.
//
// Conventions (COLMAP's): (u, v) are normalized camera-plane coordinates
// (X/Z, Y/Z); (x, y) are pixel coordinates in which pixel (col, row) covers
// [col, col+1) x [row, row+1), so its centre is at (col + 0.5, row + 0.5).
//
// Deliberate deviation: COLMAP's FOV model uses the small-omega Taylor
// expansion of the *undistortion* factor in both directions; here the
// distortion branch uses its own expansion, 1 + w^2/12 - r^2 w^2/3, so that
// ImageToWorld inverts WorldToImage for |omega| < 0.01 too.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace watergs {

constexpr int kInvalidCameraModelId = -1;

// The double value of a scalar or of a Jet's real part.
inline double ScalarValue(double value) { return value; }
template <typename T, int N>
double ScalarValue(const ceres::Jet<T, N>& value) {
  return value.a;
}

// Newton's method for the (u, v) whose distortion gives the input (u, v),
// shared by every model with a Distortion(). The solve runs in double; one
// last Newton step in T at the solution carries exact first derivatives
// (implicit function theorem) into Jets.
template <typename Model>
struct IterativeUndistorter {
  // extra: Model::kNumExtraParams values; u, v: distorted on input,
  // undistorted on output.
  template <typename T>
  static void Undistort(const T* extra, T* u, T* v) {
    using Jet2 = ceres::Jet<double, 2>;
    constexpr int kMaxIterations = 100;
    Jet2 extra_jet[Model::kNumExtraParams];
    for (int i = 0; i < Model::kNumExtraParams; ++i) {
      extra_jet[i] = Jet2(ScalarValue(extra[i]));
    }
    const Eigen::Vector2d target(ScalarValue(*u), ScalarValue(*v));
    Eigen::Vector2d x = target;
    Eigen::Matrix2d jacobian = Eigen::Matrix2d::Identity();
    for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
      Jet2 du, dv;
      Model::Distortion(extra_jet, Jet2(x(0), 0), Jet2(x(1), 1), &du, &dv);
      jacobian << 1.0 + du.v(0), du.v(1), dv.v(0), 1.0 + dv.v(1);
      const Eigen::Vector2d residual(x(0) + du.a - target(0),
                                     x(1) + dv.a - target(1));
      const Eigen::Vector2d step = jacobian.inverse() * residual;
      if (!step.allFinite()) break;
      x -= step;
      if (step.squaredNorm() < 1e-28) break;
    }
    // Final step in T: zero in value, derivative -J^-1 dResidual.
    const Eigen::Matrix2d inverse = jacobian.inverse();
    const T x0(x(0)), x1(x(1));
    T du, dv;
    Model::Distortion(extra, x0, x1, &du, &dv);
    const T r0 = x0 + du - *u;
    const T r1 = x1 + dv - *v;
    *u = x0 - (inverse(0, 0) * r0 + inverse(0, 1) * r1);
    *v = x1 - (inverse(1, 0) * r0 + inverse(1, 1) * r1);
  }
};

// Polynomial radial/tangential terms shared by the OpenCV-style models.
template <typename T>
void RadialTangential(const T& u, const T& v, const T& radial, const T& p1,
                      const T& p2, T* du, T* dv) {
  const T u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
  *du = u * radial + T(2) * p1 * uv + p2 * (r2 + T(2) * u2);
  *dv = v * radial + T(2) * p2 * uv + p1 * (r2 + T(2) * v2);
}

// Equidistant fisheye: theta_d = theta * poly(theta^2), theta = atan(r).
// coeffs: num_coeffs values k1.. of poly = 1 + k1 t^2 + k2 t^4 + ...
template <typename T>
void FisheyeDistortion(const T* coeffs, int num_coeffs, const T& u, const T& v,
                       T* du, T* dv) {
  const T r = ceres::sqrt(u * u + v * v);
  if (!(r > T(std::numeric_limits<double>::epsilon()))) {
    *du = T(0);
    *dv = T(0);
    return;
  }
  const T theta = ceres::atan(r);
  const T theta2 = theta * theta;
  T poly(1), power(1);
  for (int i = 0; i < num_coeffs; ++i) {
    power = power * theta2;
    poly = poly + coeffs[i] * power;
  }
  const T thetad = theta * poly;
  *du = u * thetad / r - u;
  *dv = v * thetad / r - v;
}

// Models with one focal length (f, cx, cy, extra...) or two
// (fx, fy, cx, cy, extra...) whose distortion is an additive Distortion().
template <typename Model, int kNumFocal>
struct DistortedModel {
  // params: kNumParams values; (u, v) normalized -> (x, y) pixels.
  template <typename T>
  static void WorldToImage(const T* params, const T u, const T v, T* x, T* y) {
    T du, dv;
    Model::Distortion(&params[kNumFocal + 2], u, v, &du, &dv);
    *x = params[0] * (u + du) + params[kNumFocal];
    *y = params[kNumFocal - 1] * (v + dv) + params[kNumFocal + 1];
  }
  // params: kNumParams values; (x, y) pixels -> (u, v) normalized.
  template <typename T>
  static void ImageToWorld(const T* params, const T x, const T y, T* u, T* v) {
    *u = (x - params[kNumFocal]) / params[0];
    *v = (y - params[kNumFocal + 1]) / params[kNumFocal - 1];
    IterativeUndistorter<Model>::Undistort(&params[kNumFocal + 2], u, v);
  }
};

// No distortion: the projection is exactly linear.
template <int kNumFocal>
struct PinholeModel {
  static constexpr int kNumParams = kNumFocal + 2;
  static constexpr int kNumExtraParams = 0;
  template <typename T>
  static void WorldToImage(const T* params, const T u, const T v, T* x, T* y) {
    *x = params[0] * u + params[kNumFocal];
    *y = params[kNumFocal - 1] * v + params[kNumFocal + 1];
  }
  template <typename T>
  static void ImageToWorld(const T* params, const T x, const T y, T* u, T* v) {
    *u = (x - params[kNumFocal]) / params[0];
    *v = (y - params[kNumFocal + 1]) / params[kNumFocal - 1];
  }
};

struct SimplePinholeCameraModel : PinholeModel<1> {
  static constexpr int kModelId = 0;
  static constexpr const char* kModelName = "SIMPLE_PINHOLE";
  static constexpr const char* kParamsInfo = "f, cx, cy";
};

struct PinholeCameraModel : PinholeModel<2> {
  static constexpr int kModelId = 1;
  static constexpr const char* kModelName = "PINHOLE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy";
};

struct SimpleRadialCameraModel : DistortedModel<SimpleRadialCameraModel, 1> {
  static constexpr int kModelId = 2;
  static constexpr const char* kModelName = "SIMPLE_RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k";
  static constexpr int kNumParams = 4;
  static constexpr int kNumExtraParams = 1;
  // extra: k. du = u * k r^2.
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    const T radial = extra[0] * (u * u + v * v);
    *du = u * radial;
    *dv = v * radial;
  }
};

struct RadialCameraModel : DistortedModel<RadialCameraModel, 1> {
  static constexpr int kModelId = 3;
  static constexpr const char* kModelName = "RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k1, k2";
  static constexpr int kNumParams = 5;
  static constexpr int kNumExtraParams = 2;
  // extra: k1, k2. du = u * (k1 r^2 + k2 r^4).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    const T r2 = u * u + v * v;
    const T radial = extra[0] * r2 + extra[1] * r2 * r2;
    *du = u * radial;
    *dv = v * radial;
  }
};

struct OpenCVCameraModel : DistortedModel<OpenCVCameraModel, 2> {
  static constexpr int kModelId = 4;
  static constexpr const char* kModelName = "OPENCV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, p1, p2";
  static constexpr int kNumParams = 8;
  static constexpr int kNumExtraParams = 4;
  // extra: k1, k2, p1, p2 (OpenCV's radial-tangential model).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    const T r2 = u * u + v * v;
    const T radial = extra[0] * r2 + extra[1] * r2 * r2;
    RadialTangential(u, v, radial, extra[2], extra[3], du, dv);
  }
};

struct OpenCVFisheyeCameraModel : DistortedModel<OpenCVFisheyeCameraModel, 2> {
  static constexpr int kModelId = 5;
  static constexpr const char* kModelName = "OPENCV_FISHEYE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, k3, k4";
  static constexpr int kNumParams = 8;
  static constexpr int kNumExtraParams = 4;
  // extra: k1..k4 of theta_d = theta (1 + k1 t^2 + k2 t^4 + k3 t^6 + k4 t^8).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    FisheyeDistortion(extra, 4, u, v, du, dv);
  }
};

struct FullOpenCVCameraModel : DistortedModel<FullOpenCVCameraModel, 2> {
  static constexpr int kModelId = 6;
  static constexpr const char* kModelName = "FULL_OPENCV";
  static constexpr const char* kParamsInfo =
      "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6";
  static constexpr int kNumParams = 12;
  static constexpr int kNumExtraParams = 8;
  // extra: k1, k2, p1, p2, k3, k4, k5, k6 (rational radial term).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    const T r2 = u * u + v * v, r4 = r2 * r2, r6 = r4 * r2;
    const T radial = (T(1) + extra[0] * r2 + extra[1] * r4 + extra[4] * r6) /
                     (T(1) + extra[5] * r2 + extra[6] * r4 + extra[7] * r6);
    RadialTangential(u, v, radial, extra[2], extra[3], du, dv);
    *du = *du - u;
    *dv = *dv - v;
  }
};

// Devernay-Faugeras field-of-view model; undistortion is closed-form.
struct FOVCameraModel {
  static constexpr int kModelId = 7;
  static constexpr const char* kModelName = "FOV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, omega";
  static constexpr int kNumParams = 5;
  static constexpr int kNumExtraParams = 1;
  // Factor r_d / r = atan(2 r tan(w/2)) / (r w), with series near w=0, r=0.
  template <typename T>
  static T DistortionFactor(const T& omega, const T& radius2) {
    const T kEpsilon(1e-4);
    const T omega2 = omega * omega;
    if (omega2 < kEpsilon) {
      return T(1) + omega2 / T(12) - omega2 * radius2 / T(3);
    }
    const T tan_half = ceres::tan(omega / T(2));
    if (radius2 < kEpsilon) {
      return T(-2) * tan_half * (T(4) * radius2 * tan_half * tan_half - T(3)) /
             (T(3) * omega);
    }
    const T radius = ceres::sqrt(radius2);
    return ceres::atan(radius * T(2) * tan_half) / (radius * omega);
  }
  // Factor r_u / r = tan(r w) / (2 r tan(w/2)), with series near w=0, r=0.
  template <typename T>
  static T UndistortionFactor(const T& omega, const T& radius2) {
    const T kEpsilon(1e-4);
    const T omega2 = omega * omega;
    if (omega2 < kEpsilon) {
      return omega2 * radius2 / T(3) - omega2 / T(12) + T(1);
    }
    const T tan_half = ceres::tan(omega / T(2));
    if (radius2 < kEpsilon) {
      return omega * (omega2 * radius2 + T(3)) / (T(6) * tan_half);
    }
    const T radius = ceres::sqrt(radius2);
    return ceres::tan(radius * omega) / (radius * T(2) * tan_half);
  }
  template <typename T>
  static void WorldToImage(const T* params, const T u, const T v, T* x, T* y) {
    const T factor = DistortionFactor(params[4], u * u + v * v);
    *x = params[0] * u * factor + params[2];
    *y = params[1] * v * factor + params[3];
  }
  template <typename T>
  static void ImageToWorld(const T* params, const T x, const T y, T* u, T* v) {
    const T ud = (x - params[2]) / params[0];
    const T vd = (y - params[3]) / params[1];
    const T factor = UndistortionFactor(params[4], ud * ud + vd * vd);
    *u = ud * factor;
    *v = vd * factor;
  }
};

struct SimpleRadialFisheyeCameraModel
    : DistortedModel<SimpleRadialFisheyeCameraModel, 1> {
  static constexpr int kModelId = 8;
  static constexpr const char* kModelName = "SIMPLE_RADIAL_FISHEYE";
  static constexpr const char* kParamsInfo = "f, cx, cy, k";
  static constexpr int kNumParams = 4;
  static constexpr int kNumExtraParams = 1;
  // extra: k of theta_d = theta (1 + k theta^2).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    FisheyeDistortion(extra, 1, u, v, du, dv);
  }
};

struct RadialFisheyeCameraModel : DistortedModel<RadialFisheyeCameraModel, 1> {
  static constexpr int kModelId = 9;
  static constexpr const char* kModelName = "RADIAL_FISHEYE";
  static constexpr const char* kParamsInfo = "f, cx, cy, k1, k2";
  static constexpr int kNumParams = 5;
  static constexpr int kNumExtraParams = 2;
  // extra: k1, k2 of theta_d = theta (1 + k1 theta^2 + k2 theta^4).
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    FisheyeDistortion(extra, 2, u, v, du, dv);
  }
};

// Equidistant projection followed by radial, tangential and thin-prism terms
// applied to the fisheye coordinates.
struct ThinPrismFisheyeCameraModel {
  static constexpr int kModelId = 10;
  static constexpr const char* kModelName = "THIN_PRISM_FISHEYE";
  static constexpr const char* kParamsInfo =
      "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1";
  static constexpr int kNumParams = 12;
  static constexpr int kNumExtraParams = 8;
  // extra: k1, k2, p1, p2, k3, k4, sx1, sy1.
  template <typename T>
  static void Distortion(const T* extra, const T u, const T v, T* du, T* dv) {
    const T r2 = u * u + v * v, r4 = r2 * r2;
    const T radial =
        extra[0] * r2 + extra[1] * r4 + extra[4] * r4 * r2 + extra[5] * r4 * r4;
    RadialTangential(u, v, radial, extra[2], extra[3], du, dv);
    *du = *du + extra[6] * r2;
    *dv = *dv + extra[7] * r2;
  }
  template <typename T>
  static void WorldToImage(const T* params, const T u, const T v, T* x, T* y) {
    const T r = ceres::sqrt(u * u + v * v);
    T uu = u, vv = v;
    if (r > T(std::numeric_limits<double>::epsilon())) {
      const T theta = ceres::atan(r);
      uu = theta * u / r;
      vv = theta * v / r;
    }
    T du, dv;
    Distortion(&params[4], uu, vv, &du, &dv);
    *x = params[0] * (uu + du) + params[2];
    *y = params[1] * (vv + dv) + params[3];
  }
  template <typename T>
  static void ImageToWorld(const T* params, const T x, const T y, T* u, T* v) {
    *u = (x - params[2]) / params[0];
    *v = (y - params[3]) / params[1];
    IterativeUndistorter<ThinPrismFisheyeCameraModel>::Undistort(&params[4], u,
                                                                 v);
    const T theta = ceres::sqrt(*u * *u + *v * *v);
    const T theta_cos_theta = theta * ceres::cos(theta);
    if (theta_cos_theta > T(std::numeric_limits<double>::epsilon())) {
      const T scale = ceres::sin(theta) / theta_cos_theta;
      *u = *u * scale;
      *v = *v * scale;
    }
  }
};

// Calls visitor(Model{}) for the model with this id; returns false for an
// unknown id. The one place that lists every model, like COLMAP's
// CAMERA_MODEL_SWITCH_CASES.
template <typename Visitor>
bool VisitCameraModel(int model_id, Visitor&& visitor) {
  switch (model_id) {
    case 0:
      visitor(SimplePinholeCameraModel{});
      return true;
    case 1:
      visitor(PinholeCameraModel{});
      return true;
    case 2:
      visitor(SimpleRadialCameraModel{});
      return true;
    case 3:
      visitor(RadialCameraModel{});
      return true;
    case 4:
      visitor(OpenCVCameraModel{});
      return true;
    case 5:
      visitor(OpenCVFisheyeCameraModel{});
      return true;
    case 6:
      visitor(FullOpenCVCameraModel{});
      return true;
    case 7:
      visitor(FOVCameraModel{});
      return true;
    case 8:
      visitor(SimpleRadialFisheyeCameraModel{});
      return true;
    case 9:
      visitor(RadialFisheyeCameraModel{});
      return true;
    case 10:
      visitor(ThinPrismFisheyeCameraModel{});
      return true;
    default:
      return false;
  }
}

constexpr int kNumCameraModels = 11;

// True for model ids 0-10.
bool ExistsCameraModelWithId(int model_id);
// True for a COLMAP model name such as "SIMPLE_RADIAL".
bool ExistsCameraModelWithName(const std::string& model_name);
// COLMAP's name for a model id; "" if unknown.
std::string CameraModelIdToName(int model_id);
// The id for a COLMAP model name; kInvalidCameraModelId if unknown.
int CameraModelNameToId(const std::string& model_name);
// Number of parameters of a model; 0 if unknown.
int CameraModelNumParams(int model_id);
// COLMAP's comma-separated parameter names, e.g. "f, cx, cy, k".
std::string CameraModelParamsInfo(int model_id);
// Whether a model has a single focal length (f) rather than fx, fy.
bool CameraModelHasSingleFocalLength(int model_id);

// Runtime dispatch of the templates in double. params must have
// CameraModelNumParams(model_id) entries (checked by the caller).
void CameraModelWorldToImage(int model_id, const std::vector<double>& params,
                             double u, double v, double* x, double* y);
void CameraModelImageToWorld(int model_id, const std::vector<double>& params,
                             double x, double y, double* u, double* v);

}  // namespace watergs
