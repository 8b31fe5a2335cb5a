// Rigid transform convention, used everywhere in the package:
//   b_from_a maps coordinates of a point in frame a into frame b:
//     x_in_b = b_from_a.rotation * x_in_a + b_from_a.translation
//   Composition: c_from_a = c_from_b * b_from_a.
// Names follow it: cam_from_site, site_from_optical, target_in_site.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace slope_monitor {

struct Rigid3 {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3() = default;
  Rigid3(const Eigen::Quaterniond& r, const Eigen::Vector3d& t)
      : rotation(r.normalized()), translation(t) {}
  Rigid3(const Eigen::Matrix3d& r, const Eigen::Vector3d& t)
      : rotation(Eigen::Quaterniond(r).normalized()), translation(t) {}

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_in_a) const {
    return rotation * x_in_a + translation;
  }
  Rigid3 operator*(const Rigid3& b_from_a) const {
    return Rigid3(rotation * b_from_a.rotation, rotation * b_from_a.translation + translation);
  }
  Rigid3 Inverse() const {
    const Eigen::Quaterniond inv = rotation.conjugate();
    return Rigid3(inv, -(inv * translation));
  }
  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
};

}  // namespace slope_monitor
