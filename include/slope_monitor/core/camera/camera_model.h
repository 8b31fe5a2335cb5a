// The collinearity camera model (doc/design.md):
//
//   x = x0 + dx - c * (m11 (X-X0) + m12 (Y-Y0) + m13 (Z-Z0)) / (m31 (X-X0) + m32 (Y-Y0) + m33
//   (Z-Z0)) y = y0 + dy - c * (m21 (X-X0) + m22 (Y-Y0) + m23 (Z-Z0)) / (m31 (X-X0) + m32 (Y-Y0) +
//   m33 (Z-Z0))
//
// Image coordinates (x, y) are millimetres in the photogrammetric image frame:
// origin at the image centre, x right, y up. The distortion (dx, dy) is a
// function of the ideal (undistorted) coordinates relative to the principal
// point, xu = -c U/W, yu = -c V/W, with r^2 = xu^2 + yu^2:
//
//   lens:     xl = xu + xu (k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 xu^2) + 2 p2 xu yu
//             yl = yu + yu (k1 r^2 + k2 r^4 + k3 r^6) + p2 (r^2 + 2 yu^2) + 2 p1 xu yu
//   sensor:   xd = xl + b1 xl + b2 yl        (affinity: aspect ratio b1, shear b2)
//             yd = yl
//   measured: x = x0 + xd,  y = y0 + yd
//
// The affinity acts on the lens-distorted image (it is a property of the
// sensor, applied to everything imaged on it); with b2 = 0 the whole model is
// then exactly OpenCV's pinhole + plumb_bob model (see ToOpenCv()).
//
// Pixels follow OpenCV: column right, row down, (0, 0) the centre of the
// top-left pixel, so the image centre is ((W-1)/2, (H-1)/2):
//   col = (W-1)/2 + x / pixel_size,   row = (H-1)/2 - y / pixel_size.
//
// Parameter blocks (used by the adjustment's cost functions):
//   exterior[6] = {X0, Y0, Z0 [m] projection centre in site; theta, phi, kappa [rad]}
//   interior[10] = {c [mm], x0 [mm], y0 [mm], k1 [mm^-2], k2 [mm^-4], k3 [mm^-6],
//                   p1 [mm^-1], p2 [mm^-1], b1 [-], b2 [-]}
#pragma once

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/rigid3.h"

namespace slope_monitor {
namespace camera {

constexpr int kNumExterior = 6;
constexpr int kNumInterior = 10;

// Indices into the interior block.
enum InteriorIndex : int {
  kC = 0,
  kX0 = 1,
  kY0 = 2,
  kK1 = 3,
  kK2 = 4,
  kK3 = 5,
  kP1 = 6,
  kP2 = 7,
  kB1 = 8,
  kB2 = 9
};
// Names of the interior parameters, in block order ("c", "x0", ..., "b2").
const std::array<const char*, kNumInterior>& InteriorNames();

// Which distortion terms a camera has. Terms outside the model must be zero.
enum class DistortionModel {
  kNone,           // "none": no distortion
  kRadial,         // "radial": k1 k2 k3
  kBrown,          // "brown": k1 k2 k3 p1 p2
  kBrownAffinity,  // "brown_affinity": k1 k2 k3 p1 p2 b1 b2
};
// Parses a model name; throws InvalidArgument naming the unknown value.
DistortionModel DistortionModelFromName(const std::string& name);
std::string DistortionModelName(DistortionModel model);
// Interior indices a model uses (always c, x0, y0, then its distortion terms).
std::vector<int> InteriorIndicesOf(DistortionModel model);

// ---------------------------------------------------------------------------
// Templated model functions (Ceres-differentiable).
// ---------------------------------------------------------------------------

// Ideal image coordinates relative to the principal point -> measured-minus-
// principal-point coordinates (lens distortion, then sensor affinity) [mm].
template <typename T>
void Distort(const T* interior, const T& xu, const T& yu, T* xd, T* yd) {
  const T r2 = xu * xu + yu * yu;
  const T radial = interior[kK1] * r2 + interior[kK2] * r2 * r2 + interior[kK3] * r2 * r2 * r2;
  const T xl =
      xu + xu * radial + interior[kP1] * (r2 + T(2) * xu * xu) + T(2) * interior[kP2] * xu * yu;
  const T yl =
      yu + yu * radial + interior[kP2] * (r2 + T(2) * yu * yu) + T(2) * interior[kP1] * xu * yu;
  *xd = xl + interior[kB1] * xl + interior[kB2] * yl;
  *yd = yl;
}

// Site point -> photogrammetric camera frame u = M (X - X0).
template <typename T>
Eigen::Matrix<T, 3, 1> PointInCamera(const T* exterior, const T* point_in_site) {
  const Eigen::Matrix<T, 3, 3> m = RotationFromAngles(exterior[3], exterior[4], exterior[5]);
  const Eigen::Matrix<T, 3, 1> d(point_in_site[0] - exterior[0], point_in_site[1] - exterior[1],
                                 point_in_site[2] - exterior[2]);
  return m * d;
}

// The collinearity equations: site point -> measured image coordinates [mm].
// Returns false when the point is not in front of the camera (W >= 0); the
// output is still written (for cost functions) unless W == 0.
template <typename T>
bool ProjectToImageMm(const T* exterior, const T* interior, const T* point_in_site, T* xy_mm) {
  const Eigen::Matrix<T, 3, 1> u = PointInCamera(exterior, point_in_site);
  if (u(2) == T(0)) return false;
  const T xu = -interior[kC] * u(0) / u(2);
  const T yu = -interior[kC] * u(1) / u(2);
  T xd, yd;
  Distort(interior, xu, yu, &xd, &yd);
  xy_mm[0] = interior[kX0] + xd;
  xy_mm[1] = interior[kY0] + yd;
  return u(2) < T(0);
}

// Sensor geometry: size in pixels and the (square) pixel pitch.
struct Sensor {
  int width = 0;            // [px]
  int height = 0;           // [px]
  double pixel_size = 0.0;  // [mm/px]; 1.0 makes "mm" mean pixels
};

template <typename T>
void MmToPixel(const Sensor& s, const T& x, const T& y, T* col, T* row) {
  *col = T(0.5 * (s.width - 1)) + x / T(s.pixel_size);
  *row = T(0.5 * (s.height - 1)) - y / T(s.pixel_size);
}

// ---------------------------------------------------------------------------
// Exterior orientation
// ---------------------------------------------------------------------------
struct ExteriorOrientation {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // X0 [m], projection centre in site
  AttitudeAngles angles;                               // [rad]

  std::array<double, kNumExterior> ToArray() const {
    return {position.x(), position.y(), position.z(), angles.theta, angles.phi, angles.kappa};
  }
  static ExteriorOrientation FromArray(const double* e);
  // Photogrammetric camera frame from site: u = M (X - X0).
  Rigid3 CamFromSite() const;
  // REP 103 optical frame from site, and the inverse (what tf publishes).
  Rigid3 OpticalFromSite() const;
  Rigid3 SiteFromOptical() const { return OpticalFromSite().Inverse(); }
  static ExteriorOrientation FromOpticalFromSite(const Rigid3& optical_from_site);
};

// A ray in the site frame: origin + t * direction (unit), t > 0 in front.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

// OpenCV's pinhole model: K = [[fx 0 cx] [0 fy cy] [0 0 1]] and the
// distortion vector (k1 k2 p1 p2 [k3 [k4 k5 k6]]).
struct OpenCvCamera {
  int width = 0;
  int height = 0;
  Eigen::Matrix3d k = Eigen::Matrix3d::Identity();
  std::vector<double> distortion;
};

// The fields of sensor_msgs/CameraInfo that describe the model (the ROS
// adapter copies them into the message). R is identity, P = [K | 0].
struct CameraInfoFields {
  int width = 0;
  int height = 0;
  std::string distortion_model;  // "plumb_bob" or "rational_polynomial"
  std::vector<double> d;
  std::array<double, 9> k{};
  std::array<double, 9> r{};
  std::array<double, 12> p{};
};

// ---------------------------------------------------------------------------
// CameraModel: sensor + interior orientation + distortion model.
// ---------------------------------------------------------------------------
class CameraModel {
 public:
  CameraModel() = default;
  CameraModel(const Sensor& sensor, DistortionModel model,
              const std::array<double, kNumInterior>& interior);

  // Throws InvalidArgument naming the parameter when any value is NaN or
  // infinite, c <= 0, the sensor size or pixel size is not positive, or a term
  // outside the distortion model is non-zero.
  void Check() const;

  const Sensor& sensor() const { return sensor_; }
  DistortionModel model() const { return model_; }
  const std::array<double, kNumInterior>& interior() const { return interior_; }
  std::array<double, kNumInterior>& mutable_interior() { return interior_; }
  double principal_distance() const { return interior_[kC]; }

  // Site point -> pixel. Returns false when the point is behind the camera.
  bool Project(const ExteriorOrientation& pose, const Eigen::Vector3d& point_in_site,
               Eigen::Vector2d* pixel) const;
  // Site point -> image coordinates [mm]. Returns false when behind.
  bool ProjectMm(const ExteriorOrientation& pose, const Eigen::Vector3d& point_in_site,
                 Eigen::Vector2d* xy_mm) const;

  // Ideal coordinates relative to the principal point -> measured image
  // coordinates [mm], and its inverse by Newton iteration (converges to 1e-12 mm
  // for any distortion the model can invert; throws InvalidArgument otherwise).
  Eigen::Vector2d DistortMm(const Eigen::Vector2d& ideal) const;
  Eigen::Vector2d UndistortMm(const Eigen::Vector2d& measured) const;

  Eigen::Vector2d MmToPixel(const Eigen::Vector2d& xy_mm) const;
  Eigen::Vector2d PixelToMm(const Eigen::Vector2d& pixel) const;

  // Pixel -> ray in the site frame (undistorted by iteration).
  Ray ImageToRay(const ExteriorOrientation& pose, const Eigen::Vector2d& pixel) const;
  // Pixel -> unit direction in the REP 103 optical frame.
  Eigen::Vector3d PixelToOpticalDirection(const Eigen::Vector2d& pixel) const;

  // Conversions to and from OpenCV. ToOpenCv throws InvalidArgument when the
  // shear b2 is non-zero (OpenCV's projectPoints has no skew). FromOpenCv
  // needs the pixel size (1.0 keeps everything in pixels) and throws when K
  // has skew or the distortion vector has non-zero terms past k3 (k4..k6,
  // thin prism, tilt), naming the coefficient.
  OpenCvCamera ToOpenCv() const;
  static CameraModel FromOpenCv(const OpenCvCamera& cv_camera, double pixel_size);

  // Conversions to and from the CameraInfo fields. FromCameraInfo accepts
  // "plumb_bob" and "rational_polynomial" (with k4..k6 zero); any other
  // distortion model name is an InvalidArgument naming it.
  CameraInfoFields ToCameraInfo() const;
  static CameraModel FromCameraInfo(const CameraInfoFields& info, double pixel_size);

 private:
  Sensor sensor_;
  DistortionModel model_ = DistortionModel::kNone;
  std::array<double, kNumInterior> interior_{};
};

}  // namespace camera
}  // namespace slope_monitor
