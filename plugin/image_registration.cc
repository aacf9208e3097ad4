// Registration of images without a pose (see image_registration.h).
#include "plugin/image_registration.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"

namespace watergs {
namespace {

// 8-bit grey of a float RGB image in [0, 1].
cv::Mat Grey(const ImageRGB& image) {
  cv::Mat rgb(image.height, image.width, CV_32FC3,
              const_cast<float*>(image.data.data()));
  cv::Mat grey, grey8;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  grey.convertTo(grey8, CV_8U, 255.0);
  return grey8;
}

// A SIFT keypoint's position in the convention of RenderCamera and COLMAP (a
// pixel's centre at col + 0.5), `scale` times smaller than the image it was
// found in. OpenCV puts a pixel's centre at col, and its SIFT (4.x, without
// precise upscaling) halves positions found in a double-size first octave made
// by a linear resize, which reports them 0.25 px past OpenCV's centre: 0.25
// more makes COLMAP's. Left uncorrected, every pose came out 0.35 px off
// (ImageRegistration.PhotosLeftOutOfTheIndexRegisterWhereTheyWereTaken).
cv::Point2f PixelPosition(const cv::KeyPoint& k, double scale = 1) {
  constexpr float kSiftToPixelCentre = 0.25f;
  return (k.pt + cv::Point2f(kSiftToPixelCentre, kSiftToPixelCentre)) *
         float(1 / scale);
}

cv::Matx33d Intrinsics(const RenderCamera& c) {
  return {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
}

// RMS reprojection error of `inliers` under K, rvec, tvec.
double RmsError(const std::vector<cv::Point3d>& object,
                const std::vector<cv::Point2d>& pixels, const cv::Matx33d& K,
                const cv::Mat& rvec, const cv::Mat& tvec) {
  std::vector<cv::Point2d> projected;
  cv::projectPoints(object, rvec, tvec, K, cv::noArray(), projected);
  double sum = 0;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const cv::Point2d d = projected[i] - pixels[i];
    sum += d.dot(d);
  }
  return std::sqrt(sum / std::max<size_t>(1, pixels.size()));
}

// `camera` with intrinsics K and OpenCV's pose (rvec, tvec).
RenderCamera WithPose(RenderCamera camera, const cv::Matx33d& K,
                      const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  cv::cv2eigen(R, camera.R);
  cv::cv2eigen(tvec, camera.t);
  camera.fx = K(0, 0);
  camera.fy = K(1, 1);
  camera.cx = K(0, 2);
  camera.cy = K(1, 2);
  return camera;
}

// Median camera depth of `points` (non-empty) seen from `camera`.
double MedianDepth(const RenderCamera& camera,
                   const std::vector<cv::Point3d>& points) {
  std::vector<double> depths;
  for (const cv::Point3d& X : points) {
    depths.push_back(
        (camera.R * Eigen::Vector3d(X.x, X.y, X.z) + camera.t).z());
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                   depths.end());
  return depths[depths.size() / 2];
}

// The world point under a render's pixel position `at` (RenderCamera's
// convention, a pixel's centre at col + 0.5) through its depth map, read
// bilinearly (an oblique wall's depth changes across a pixel); false off the
// map, on the background or at a depth edge (the 4 x 4 pixels around differ
// by more than 2%: a blend of two surfaces, at neither).
bool LiftToWorld(const RenderCamera& camera, const std::vector<float>& depth,
                 const cv::Point2d& at, cv::Point3d* world) {
  const double x = at.x - 0.5, y = at.y - 0.5;  // in pixel-index units
  const int u = int(std::floor(x)), v = int(std::floor(y));
  if (u < 1 || v < 1 || u + 2 >= camera.width || v + 2 >= camera.height) {
    return false;
  }
  auto at_pixel = [&](int uu, int vv) {
    return depth[size_t(vv) * camera.width + uu];
  };
  float lo = at_pixel(u, v), hi = lo;
  for (int dv = -1; dv <= 2; ++dv) {
    for (int du = -1; du <= 2; ++du) {
      const float d = at_pixel(u + du, v + dv);
      if (!std::isfinite(d)) return false;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  if (!(lo > 0) || hi - lo > 0.02 * lo) return false;
  const double fu = x - u, fv = y - v;
  const double d =
      (1 - fv) * ((1 - fu) * at_pixel(u, v) + fu * at_pixel(u + 1, v)) +
      fv * ((1 - fu) * at_pixel(u, v + 1) + fu * at_pixel(u + 1, v + 1));
  const Eigen::Vector3d in_camera((at.x - camera.cx) / camera.fx * d,
                                  (at.y - camera.cy) / camera.fy * d, d);
  const Eigen::Vector3d X = camera.R.transpose() * (in_camera - camera.t);
  *world = {X.x(), X.y(), X.z()};
  return true;
}

// SIFT features of `image`, positions in its pixels. An image narrower than
// `search_width` is searched upsampled to it (its features would be too few
// and too coarse), then the positions scaled back.
void Features(cv::SIFT& sift, const ImageRGB& image, int search_width,
              std::vector<cv::Point2d>* positions, cv::Mat* descriptors) {
  cv::Mat grey = Grey(image);
  double up = std::max(1.0, double(search_width) / image.width);
  if (up > 1.05) {
    cv::resize(grey, grey, cv::Size(), up, up, cv::INTER_CUBIC);
    up = double(grey.cols) / image.width;  // the size was rounded
  } else {
    up = 1;
  }
  std::vector<cv::KeyPoint> keypoints;
  sift.detectAndCompute(grey, cv::noArray(), keypoints, *descriptors);
  positions->clear();
  for (const cv::KeyPoint& k : keypoints) {
    positions->push_back(PixelPosition(k, up));
  }
}

}  // namespace

struct ImageRegistrar::Index {
  cv::Mat descriptors;  // one SIFT row per anchored feature
  std::vector<cv::Point3d> points;
  // A lower contrast threshold than SIFT's 0.04: renders and small photos
  // have few strong corners.
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(0, 3, 0.02);
  cv::FlannBasedMatcher matcher;
  // Index points closer than this (world units) are one point to the ratio
  // test: a point seen in several photos or renders has a feature in each.
  double distinct = 0;

  // (Re)builds the matcher and `distinct` (1% of the points' RMS spread).
  void Train() {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const cv::Point3d& X : points) mean += Eigen::Vector3d(X.x, X.y, X.z);
    mean /= double(points.size());
    double spread = 0;
    for (const cv::Point3d& X : points) {
      spread += (Eigen::Vector3d(X.x, X.y, X.z) - mean).squaredNorm();
    }
    distinct = 0.01 * std::sqrt(spread / double(points.size()));
    matcher.clear();
    matcher.add(std::vector<cv::Mat>{descriptors});
    // FLANN's randomised kd-trees draw from OpenCV's thread RNG: seeded
    // here, the trees (and so every match) are a function of the index
    // alone, the same whether it was built in this process or read from a
    // file, and whatever drew from the RNG before.
    const cv::RNG outer = cv::theRNG();
    cv::theRNG() = cv::RNG(kTreeSeed);
    matcher.train();
    cv::theRNG() = outer;
  }
  static constexpr uint64_t kTreeSeed = 0x5eed1dc5;

  // Matches of query features (rows of `query`, at `positions`) to index
  // points passing Lowe's ratio test, the second neighbour being the nearest
  // one on another point (of the 8 nearest; all on one point pass).
  void Match(const cv::Mat& query, const std::vector<cv::Point2d>& positions,
             double ratio, std::vector<cv::Point3d>* object,
             std::vector<cv::Point2d>* pixels) {
    if (query.empty() || points.empty()) return;
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(query, knn, 8);
    for (const auto& m : knn) {
      if (m.empty()) continue;
      const cv::Point3d& best = points[size_t(m[0].trainIdx)];
      bool unique = true;
      for (size_t j = 1; j < m.size(); ++j) {
        if (cv::norm(points[size_t(m[j].trainIdx)] - best) <= distinct) {
          continue;
        }
        unique = m[0].distance < ratio * m[j].distance;
        break;
      }
      if (!unique) continue;
      object->push_back(best);
      pixels->push_back(positions[size_t(m[0].queryIdx)]);
    }
  }
};

ImageRegistrar::ImageRegistrar(const Workspace& workspace,
                               const TrainingViews& views,
                               const RegistrationOptions& options)
    : index_(std::make_unique<Index>()), options_(options) {
  if (views.NumViews() == 0) Fail("registration: the workspace has no view");
  reference_ = views.Camera(0);
  const Reconstruction& model = workspace.reconstruction();
  for (size_t v = 0; v < views.NumViews(); ++v) {
    if (std::count(options.skip_views.begin(), options.skip_views.end(), v)) {
      continue;
    }
    const RenderCamera camera = views.Camera(v);
    // The view's SfM points projected into its (undistorted, scaled) image.
    std::vector<cv::Point2f> projected;
    std::vector<cv::Point3d> anchors;
    for (const Point2D& p : workspace.ViewImage(v).points2D) {
      if (!p.HasPoint3D() || !model.ExistsPoint3D(p.point3D_id)) continue;
      const Eigen::Vector3d X = model.GetPoint3D(p.point3D_id).xyz;
      const Eigen::Vector3d x = camera.R * X + camera.t;
      if (x.z() <= camera.near_plane) continue;
      projected.emplace_back(float(camera.fx * x.x() / x.z() + camera.cx),
                             float(camera.fy * x.y() / x.z() + camera.cy));
      anchors.emplace_back(X.x(), X.y(), X.z());
    }
    if (projected.empty()) continue;
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    index_->sift->detectAndCompute(Grey(*views.Image(v)), cv::noArray(),
                                   keypoints, descriptors);
    const double max_d2 = options.associate_px * options.associate_px;
    for (size_t k = 0; k < keypoints.size(); ++k) {
      double best = max_d2;
      int found = -1;
      for (size_t j = 0; j < projected.size(); ++j) {
        const cv::Point2f d = PixelPosition(keypoints[k]) - projected[j];
        const double d2 = d.dot(d);
        if (d2 <= best) best = d2, found = int(j);
      }
      if (found < 0) continue;
      index_->descriptors.push_back(descriptors.row(int(k)));
      index_->points.push_back(anchors[size_t(found)]);
    }
  }
  if (index_->points.empty()) {
    Fail("registration: no photo of " + workspace.options().workspace_path +
         " has a SIFT feature on an SfM point");
  }
  index_->Train();
}

void ImageRegistrar::AddRenders(const std::vector<RenderCamera>& cameras,
                                const RenderFunction& render,
                                const DepthFunction& depth) {
  for (const RenderCamera& camera : cameras) {
    std::vector<cv::Point2d> positions;
    cv::Mat descriptors;
    Features(*index_->sift, render(camera), reference_.width, &positions,
             &descriptors);
    const std::vector<float> depths = depth(camera);
    for (size_t k = 0; k < positions.size(); ++k) {
      cv::Point3d X;
      if (!LiftToWorld(camera, depths, positions[k], &X)) continue;
      index_->descriptors.push_back(descriptors.row(int(k)));
      index_->points.push_back(X);
    }
  }
  if (!index_->points.empty()) index_->Train();
}

ImageRegistrar::ImageRegistrar(const RenderCamera& reference,
                               const RegistrationOptions& options)
    : index_(std::make_unique<Index>()),
      options_(options),
      reference_(reference) {}

ImageRegistrar::~ImageRegistrar() = default;
ImageRegistrar::ImageRegistrar(ImageRegistrar&&) noexcept = default;
ImageRegistrar& ImageRegistrar::operator=(ImageRegistrar&&) noexcept = default;

namespace {

// The index file (ImageRegistrar::Save): a header, the reference camera,
// the descriptors, the points, the checksum.
constexpr char kIndexMagic[8] = "WGSIDX1";
constexpr uint32_t kIndexVersion = 1;
constexpr uint32_t kFloatDescriptors = 0, kByteDescriptors = 1;
// magic, version, encoding, features, columns, reserved.
constexpr size_t kIndexHeaderBytes = 8 + 4 + 4 + 8 + 4 + 4;
// width, height, fx, fy, cx, cy, R (row-major), t, near, far.
constexpr size_t kIndexCameraBytes = 2 * 4 + (4 + 9 + 3 + 2) * 8;

template <typename T>
void Put(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// Reads the file's bytes in order; the sizes were checked before.
class Reader {
 public:
  explicit Reader(const std::vector<uint8_t>& bytes) : bytes_(bytes) {}
  template <typename T>
  T Get() {
    T value;
    std::memcpy(&value, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  const uint8_t* Take(size_t size) {
    const uint8_t* p = bytes_.data() + at_;
    at_ += size;
    return p;
  }

 private:
  const std::vector<uint8_t>& bytes_;
  size_t at_ = 0;
};

bool LittleEndian() {
  const uint16_t one = 1;
  uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

}  // namespace

void ImageRegistrar::Save(const std::string& path) const {
  if (!LittleEndian()) FailAt(path, "index files are little-endian only");
  const cv::Mat& d = index_->descriptors;
  const uint64_t n = index_->points.size();
  const uint32_t columns = n == 0 ? 128 : uint32_t(d.cols);
  bool bytes = true;  // every value an integer in [0, 255]
  for (int r = 0; r < d.rows && bytes; ++r) {
    const float* row = d.ptr<float>(r);
    for (int c = 0; c < d.cols; ++c) {
      if (!(row[c] >= 0 && row[c] <= 255 && row[c] == std::floor(row[c]))) {
        bytes = false;
        break;
      }
    }
  }
  std::string out;
  out.reserve(kIndexHeaderBytes + kIndexCameraBytes +
              n * (columns * (bytes ? 1 : 4) + 3 * 8) + 8);
  out.append(kIndexMagic, 8);
  Put(&out, kIndexVersion);
  Put(&out, bytes ? kByteDescriptors : kFloatDescriptors);
  Put(&out, n);
  Put(&out, columns);
  Put(&out, uint32_t(0));
  const RenderCamera& c = reference_;
  Put(&out, int32_t(c.width));
  Put(&out, int32_t(c.height));
  for (double v : {c.fx, c.fy, c.cx, c.cy}) Put(&out, v);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) Put(&out, c.R(i, j));
  }
  for (int i = 0; i < 3; ++i) Put(&out, c.t(i));
  Put(&out, c.near_plane);
  Put(&out, c.far_plane);
  for (int r = 0; r < d.rows; ++r) {
    const float* row = d.ptr<float>(r);
    for (int k = 0; k < d.cols; ++k) {
      if (bytes) {
        Put(&out, uint8_t(row[k]));
      } else {
        Put(&out, row[k]);
      }
    }
  }
  for (const cv::Point3d& X : index_->points) {
    Put(&out, X.x);
    Put(&out, X.y);
    Put(&out, X.z);
  }
  Put(&out, Fnv1a64(out.data(), out.size()));
  AtomicWriteFile(path, out);
}

ImageRegistrar ImageRegistrar::Load(const std::string& path,
                                    const RegistrationOptions& options) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  const std::string what = "watergs registration index";
  if (!bytes.empty() && std::memcmp(bytes.data(), kIndexMagic,
                                    std::min<size_t>(bytes.size(), 8)) != 0) {
    FailAt(path, "not a " + what + " (no WGSIDX1 header)");
  }
  const size_t fixed = kIndexHeaderBytes + kIndexCameraBytes + 8;
  if (bytes.size() < fixed) {
    FailAt(path, "truncated " + what + " (" + std::to_string(bytes.size()) +
                     " bytes, shorter than its header)");
  }
  if (!LittleEndian()) FailAt(path, "index files are little-endian only");
  Reader in(bytes);
  in.Take(8);
  const auto version = in.Get<uint32_t>();
  if (version != kIndexVersion) {
    FailAt(path, what + " of format version " + std::to_string(version) +
                     " (this build reads version " +
                     std::to_string(kIndexVersion) + ")");
  }
  const auto encoding = in.Get<uint32_t>();
  const auto n = in.Get<uint64_t>();
  const auto columns = in.Get<uint32_t>();
  in.Get<uint32_t>();
  if ((encoding != kFloatDescriptors && encoding != kByteDescriptors) ||
      columns != 128 || n > bytes.size()) {
    FailAt(path, "corrupted " + what + " (a header field is out of range)");
  }
  const size_t descriptor_bytes =
      size_t(n) * columns * (encoding == kByteDescriptors ? 1 : 4);
  const size_t expected = fixed + descriptor_bytes + size_t(n) * 3 * 8;
  if (bytes.size() != expected) {
    FailAt(path, (bytes.size() < expected ? "truncated " : "corrupted ") +
                     what + " (" + std::to_string(bytes.size()) +
                     " bytes where its header says " +
                     std::to_string(expected) + ")");
  }
  uint64_t checksum;
  std::memcpy(&checksum, bytes.data() + bytes.size() - 8, 8);
  if (checksum != Fnv1a64(bytes.data(), bytes.size() - 8)) {
    FailAt(path, "corrupted " + what + " (checksum mismatch)");
  }
  RenderCamera c;
  c.width = in.Get<int32_t>();
  c.height = in.Get<int32_t>();
  c.fx = in.Get<double>();
  c.fy = in.Get<double>();
  c.cx = in.Get<double>();
  c.cy = in.Get<double>();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c.R(i, j) = in.Get<double>();
  }
  for (int i = 0; i < 3; ++i) c.t(i) = in.Get<double>();
  c.near_plane = in.Get<double>();
  c.far_plane = in.Get<double>();
  ImageRegistrar registrar(c, options);
  Index& index = *registrar.index_;
  if (n > 0) {
    index.descriptors.create(int(n), int(columns), CV_32F);
    const uint8_t* p = in.Take(descriptor_bytes);
    if (encoding == kByteDescriptors) {
      cv::Mat(int(n), int(columns), CV_8U, const_cast<uint8_t*>(p))
          .convertTo(index.descriptors, CV_32F);
    } else {
      std::memcpy(index.descriptors.data, p, descriptor_bytes);
    }
  }
  index.points.resize(size_t(n));
  for (cv::Point3d& X : index.points) {
    X.x = in.Get<double>();
    X.y = in.Get<double>();
    X.z = in.Get<double>();
  }
  if (n > 0) index.Train();
  return registrar;
}

size_t ImageRegistrar::IndexSize() const { return index_->points.size(); }

namespace {

// Registration::alternatives: RANSAC again on the matches no pose so far
// explains, while a pose keeps enough of them.
std::vector<RenderCamera> AlternativePoses(
    const std::vector<cv::Point3d>& object,
    const std::vector<cv::Point2d>& pixels, const std::vector<int>& inliers,
    const cv::Matx33d& K, const RenderCamera& camera,
    const RegistrationOptions& options) {
  std::vector<bool> used(object.size(), false);
  for (int i : inliers) used[size_t(i)] = true;
  std::vector<RenderCamera> poses;
  while (int(poses.size()) < options.max_alternatives) {
    std::vector<cv::Point3d> rest_object;
    std::vector<cv::Point2d> rest_pixels;
    std::vector<size_t> rest_index;
    for (size_t i = 0; i < object.size(); ++i) {
      if (used[i]) continue;
      rest_object.push_back(object[i]);
      rest_pixels.push_back(pixels[i]);
      rest_index.push_back(i);
    }
    if (int(rest_object.size()) < options.alternative_inliers) break;
    cv::Mat rvec, tvec;
    std::vector<int> in;
    const bool ok = cv::solvePnPRansac(
        rest_object, rest_pixels, K, cv::noArray(), rvec, tvec, false, 2000,
        float(options.inlier_px), 0.999, in, cv::SOLVEPNP_SQPNP);
    if (!ok || int(in.size()) < options.alternative_inliers) break;
    for (int i : in) used[rest_index[size_t(i)]] = true;
    poses.push_back(WithPose(camera, K, rvec, tvec));
  }
  return poses;
}

}  // namespace

Registration ImageRegistrar::Register(const ImageRGB& image) const {
  Registration r;
  std::vector<cv::Point2d> positions;
  cv::Mat descriptors;
  Features(*index_->sift, image, reference_.width, &positions, &descriptors);
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> pixels;
  index_->Match(descriptors, positions, options_.ratio, &object, &pixels);
  r.matches = int(object.size());
  if (r.matches < options_.min_inliers) {
    r.why = std::to_string(positions.size()) + " features, " +
            std::to_string(r.matches) +
            " matched to the workspace's SfM points (" +
            std::to_string(options_.min_inliers) + " needed)";
    return r;
  }
  // Start from the workspace camera, centred on the image, with its focal
  // length as a resize would scale it or as a crop keeps it: the one more
  // points agree with.
  RenderCamera camera = reference_;
  camera.width = image.width;
  camera.height = image.height;
  camera.cx = image.width / 2.0;
  camera.cy = image.height / 2.0;
  cv::Matx33d K;
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  bool solved = false;
  for (const double scale : {double(image.width) / reference_.width, 1.0}) {
    RenderCamera guess = camera;
    guess.fx = reference_.fx * scale;
    guess.fy = reference_.fy * scale;
    const cv::Matx33d K_guess = Intrinsics(guess);
    cv::Mat r_guess, t_guess;
    std::vector<int> in_guess;
    const bool ok = cv::solvePnPRansac(
        object, pixels, K_guess, cv::noArray(), r_guess, t_guess, false, 2000,
        float(options_.inlier_px), 0.999, in_guess, cv::SOLVEPNP_SQPNP);
    if (ok && in_guess.size() > inliers.size()) {
      solved = true;
      K = K_guess;
      rvec = r_guess;
      tvec = t_guess;
      inliers = std::move(in_guess);
    }
  }
  r.inliers = int(inliers.size());
  if (!solved || r.inliers < options_.min_inliers) {
    r.why = std::to_string(r.matches) + " matches, " +
            std::to_string(r.inliers) + " consistent with one pose (" +
            std::to_string(options_.min_inliers) + " needed)";
    return r;
  }
  r.alternatives =
      AlternativePoses(object, pixels, inliers, K, camera, options_);
  std::vector<cv::Point3d> in_object;
  std::vector<cv::Point2d> in_pixels;
  for (int i : inliers) {
    in_object.push_back(object[size_t(i)]);
    in_pixels.push_back(pixels[size_t(i)]);
  }
  cv::solvePnP(in_object, in_pixels, K, cv::noArray(), rvec, tvec, true,
               cv::SOLVEPNP_ITERATIVE);
  r.rms_px = RmsError(in_object, in_pixels, K, rvec, tvec);
  r.guessed_camera = WithPose(camera, K, rvec, tvec);
  // Focal length and principal point refined with the pose (a crop or a
  // resize changed them); kept only if the fit improves and stays sane.
  {
    cv::Mat K_refined = cv::Mat(K).clone(), dist = cv::Mat::zeros(5, 1, CV_64F);
    std::vector<cv::Mat> rvecs, tvecs;
    std::vector<cv::Point3f> object_f(in_object.begin(), in_object.end());
    std::vector<cv::Point2f> pixels_f(in_pixels.begin(), in_pixels.end());
    const int flags = cv::CALIB_USE_INTRINSIC_GUESS |
                      cv::CALIB_FIX_ASPECT_RATIO | cv::CALIB_ZERO_TANGENT_DIST |
                      cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3;
    try {
      cv::calibrateCamera(std::vector<std::vector<cv::Point3f>>{object_f},
                          std::vector<std::vector<cv::Point2f>>{pixels_f},
                          cv::Size(image.width, image.height), K_refined, dist,
                          rvecs, tvecs, flags);
      cv::Matx33d K2(K_refined);
      const double rms = RmsError(in_object, in_pixels, K2, rvecs[0], tvecs[0]);
      const bool sane = K2(0, 0) > 0.5 * K(0, 0) && K2(0, 0) < 2 * K(0, 0) &&
                        std::abs(K2(0, 2) - K(0, 2)) < image.width &&
                        std::abs(K2(1, 2) - K(1, 2)) < image.height;
      if (sane && rms < r.rms_px) {
        K = K2;
        rvec = rvecs[0];
        tvec = tvecs[0];
        r.rms_px = rms;
      }
    } catch (const cv::Exception&) {
      // Degenerate geometry: keep the PnP pose at the guessed intrinsics.
    }
  }
  camera = WithPose(camera, K, rvec, tvec);
  r.depth = MedianDepth(camera, in_object);
  r.camera = camera;
  r.registered = true;
  return r;
}

}  // namespace watergs
