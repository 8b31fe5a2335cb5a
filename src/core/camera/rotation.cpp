#include "slope_monitor/core/camera/rotation.h"

#include <cmath>

namespace slope_monitor {
namespace camera {

AttitudeAngles AnglesFromRotation(const Eigen::Matrix3d& m) {
  // Row 3 of M is (cos phi sin theta, sin phi, cos phi cos theta); m12 and m22
  // are (sin kappa cos phi, cos kappa cos phi).
  AttitudeAngles a;
  const double cos_phi = std::hypot(m(2, 0), m(2, 2));
  a.phi = std::atan2(m(2, 1), cos_phi);
  if (cos_phi > kGimbalLockCosPhi) {
    a.theta = std::atan2(m(2, 0), m(2, 2));
    a.kappa = std::atan2(m(0, 1), m(1, 1));
  } else {
    // phi = +-pi/2: with theta = 0, m11 = cos kappa and m21 = -sin kappa.
    a.theta = 0.0;
    a.kappa = std::atan2(-m(1, 0), m(0, 0));
  }
  return a;
}

Eigen::Quaterniond QuaternionFromAngles(const AttitudeAngles& a) {
  return Eigen::Quaterniond(RotationFromAngles(a)).normalized();
}

AttitudeAngles AnglesFromQuaternion(const Eigen::Quaterniond& q) {
  return AnglesFromRotation(q.normalized().toRotationMatrix());
}

Eigen::Quaterniond SiteFromOpticalFromAngles(const AttitudeAngles& a) {
  const Eigen::Matrix3d optical_from_site = OpticalFromPhotogrammetric() * RotationFromAngles(a);
  return Eigen::Quaterniond(optical_from_site.transpose()).normalized();
}

AttitudeAngles AnglesFromSiteFromOptical(const Eigen::Quaterniond& site_from_optical) {
  const Eigen::Matrix3d optical_from_site =
      site_from_optical.normalized().toRotationMatrix().transpose();
  return AnglesFromRotation(OpticalFromPhotogrammetric() * optical_from_site);
}

}  // namespace camera
}  // namespace slope_monitor
