// Camera attitude of the collinearity model (doc/design.md, "Collinearity and
// camera attitude").
//
//   M = m_kappa * m_phi * m_theta
//   theta: azimuth about Y, phi: elevation about X, kappa: roll about Z [rad]
//
//   m_theta = [[cos t, 0, -sin t], [0, 1, 0], [sin t, 0, cos t]]
//   m_phi   = [[1, 0, 0], [0, cos p, -sin p], [0, sin p, cos p]]
//   m_kappa = [[cos k, sin k, 0], [-sin k, cos k, 0], [0, 0, 1]]
//
// M maps site-frame differences (X - X0) into the photogrammetric camera
// frame (x right, y up, the camera looks along -z):  u = M * (X - X0).
// So M is the rotation of cam_from_site (photogrammetric camera frame).
// With theta = phi = kappa = 0 the camera looks straight down (nadir).
//
// The REP 103 optical frame (x right, y down, z forward) differs from the
// photogrammetric camera frame by a half turn about x:
//   optical_from_cam = diag(1, -1, -1).
#pragma once

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace slope_monitor {
namespace camera {

// Attitude angles of the collinearity model [rad].
struct AttitudeAngles {
  double theta = 0.0;  // azimuth, about Y
  double phi = 0.0;    // elevation, about X
  double kappa = 0.0;  // roll, about Z
};

template <typename T>
Eigen::Matrix<T, 3, 3> MTheta(const T& theta) {
  using std::cos;
  using std::sin;
  Eigen::Matrix<T, 3, 3> m;
  m << cos(theta), T(0), -sin(theta), T(0), T(1), T(0), sin(theta), T(0), cos(theta);
  return m;
}

template <typename T>
Eigen::Matrix<T, 3, 3> MPhi(const T& phi) {
  using std::cos;
  using std::sin;
  Eigen::Matrix<T, 3, 3> m;
  m << T(1), T(0), T(0), T(0), cos(phi), -sin(phi), T(0), sin(phi), cos(phi);
  return m;
}

template <typename T>
Eigen::Matrix<T, 3, 3> MKappa(const T& kappa) {
  using std::cos;
  using std::sin;
  Eigen::Matrix<T, 3, 3> m;
  m << cos(kappa), sin(kappa), T(0), -sin(kappa), cos(kappa), T(0), T(0), T(0), T(1);
  return m;
}

// M from (theta, phi, kappa), element by element as doc/design.md lists them
// (equal to MKappa(kappa) * MPhi(phi) * MTheta(theta)). Templated so Ceres
// can differentiate it.
template <typename T>
Eigen::Matrix<T, 3, 3> RotationFromAngles(const T& theta, const T& phi, const T& kappa) {
  using std::cos;
  using std::sin;
  const T ct = cos(theta), st = sin(theta);
  const T cp = cos(phi), sp = sin(phi);
  const T ck = cos(kappa), sk = sin(kappa);
  Eigen::Matrix<T, 3, 3> m;
  m(0, 0) = ck * ct - sk * sp * st;
  m(0, 1) = sk * cp;
  m(0, 2) = -ck * st - sk * sp * ct;
  m(1, 0) = -sk * ct - ck * sp * st;
  m(1, 1) = ck * cp;
  m(1, 2) = sk * st - ck * sp * ct;
  m(2, 0) = cp * st;
  m(2, 1) = sp;
  m(2, 2) = cp * ct;
  return m;
}

inline Eigen::Matrix3d RotationFromAngles(const AttitudeAngles& a) {
  return RotationFromAngles<double>(a.theta, a.phi, a.kappa);
}

// Threshold on cos(phi) below which the attitude is treated as gimbal-locked
// (phi = +-pi/2): theta and kappa then turn about the same axis and only their
// combination is defined; we return theta = 0 and put the whole turn in kappa.
constexpr double kGimbalLockCosPhi = 1e-12;

// (theta, phi, kappa) from a rotation matrix M (any proper rotation).
// phi in [-pi/2, pi/2]; theta, kappa in (-pi, pi].
AttitudeAngles AnglesFromRotation(const Eigen::Matrix3d& m);

// The half turn between the photogrammetric camera frame and the REP 103
// optical frame (its own inverse).
inline Eigen::Matrix3d OpticalFromPhotogrammetric() {
  return Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
}

// Quaternion of cam_from_site (photogrammetric) for the given angles, and back.
Eigen::Quaterniond QuaternionFromAngles(const AttitudeAngles& a);
AttitudeAngles AnglesFromQuaternion(const Eigen::Quaterniond& q);

// Rotation of site_from_optical (what tf publishes for a camera's optical
// frame under the site frame) from the attitude angles, and back.
Eigen::Quaterniond SiteFromOpticalFromAngles(const AttitudeAngles& a);
AttitudeAngles AnglesFromSiteFromOptical(const Eigen::Quaterniond& site_from_optical);

}  // namespace camera
}  // namespace slope_monitor
