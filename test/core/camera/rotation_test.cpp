// Rotation of the collinearity model, checked against the matrices printed in
// doc/design.md and by round trips.
#include "slope_monitor/core/camera/rotation.h"

#include <cmath>

#include <gtest/gtest.h>

namespace slope_monitor {
namespace camera {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTol = 1e-14;

TEST(Rotation, ThetaOnlyIsThePrintedMTheta) {
  const double t = 0.3;
  const Eigen::Matrix3d m = RotationFromAngles(t, 0.0, 0.0);
  Eigen::Matrix3d expected;
  expected << std::cos(t), 0, -std::sin(t), 0, 1, 0, std::sin(t), 0, std::cos(t);
  EXPECT_TRUE(m.isApprox(expected, kTol)) << m;
  EXPECT_TRUE(MTheta(t).isApprox(expected, kTol));
}

TEST(Rotation, PhiOnlyIsThePrintedMPhi) {
  const double p = -0.7;
  const Eigen::Matrix3d m = RotationFromAngles(0.0, p, 0.0);
  Eigen::Matrix3d expected;
  expected << 1, 0, 0, 0, std::cos(p), -std::sin(p), 0, std::sin(p), std::cos(p);
  EXPECT_TRUE(m.isApprox(expected, kTol)) << m;
  EXPECT_TRUE(MPhi(p).isApprox(expected, kTol));
}

TEST(Rotation, KappaOnlyIsThePrintedMKappa) {
  const double k = 1.1;
  const Eigen::Matrix3d m = RotationFromAngles(0.0, 0.0, k);
  Eigen::Matrix3d expected;
  expected << std::cos(k), std::sin(k), 0, -std::sin(k), std::cos(k), 0, 0, 0, 1;
  EXPECT_TRUE(m.isApprox(expected, kTol)) << m;
  EXPECT_TRUE(MKappa(k).isApprox(expected, kTol));
}

TEST(Rotation, ElementListEqualsProductKappaPhiTheta) {
  for (double t : {-2.5, -0.4, 0.0, 0.9, 3.0}) {
    for (double p : {-1.2, -0.1, 0.5, 1.4}) {
      for (double k : {-3.0, 0.2, 2.2}) {
        const Eigen::Matrix3d product = MKappa(k) * MPhi(p) * MTheta(t);
        EXPECT_LT((RotationFromAngles(t, p, k) - product).cwiseAbs().maxCoeff(), 1e-15);
      }
    }
  }
}

TEST(Rotation, HandCheckedQuarterTurns) {
  // theta = 90 deg: m31 = cos(phi) sin(theta) = 1, m13 = -1, m22 = 1.
  const Eigen::Matrix3d m = RotationFromAngles(kPi / 2, 0.0, 0.0);
  EXPECT_NEAR(m(2, 0), 1.0, kTol);
  EXPECT_NEAR(m(0, 2), -1.0, kTol);
  EXPECT_NEAR(m(1, 1), 1.0, kTol);
  // Identity attitude looks straight down: the camera's -z axis is site -z.
  const Eigen::Matrix3d nadir = RotationFromAngles(0.0, 0.0, 0.0);
  EXPECT_TRUE(nadir.isIdentity(kTol));
}

TEST(Rotation, IsProperOrthonormal) {
  const Eigen::Matrix3d m = RotationFromAngles(0.3, -0.8, 2.0);
  EXPECT_TRUE((m * m.transpose()).isIdentity(1e-14));
  EXPECT_NEAR(m.determinant(), 1.0, 1e-14);
}

TEST(Rotation, AnglesRoundTripOverAGrid) {
  int checked = 0;
  for (int it = -17; it <= 17; ++it) {
    for (int ip = -8; ip <= 8; ++ip) {
      for (int ik = -17; ik <= 17; ++ik) {
        const double t = it * kPi / 18.0 + 0.013, p = ip * kPi / 18.5, k = ik * kPi / 18.0 - 0.007;
        const AttitudeAngles a = AnglesFromRotation(RotationFromAngles(t, p, k));
        EXPECT_NEAR(a.theta, t, 1e-12);
        EXPECT_NEAR(a.phi, p, 1e-12);
        EXPECT_NEAR(a.kappa, k, 1e-12);
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 35 * 17 * 35);
}

TEST(Rotation, NearAndAtGimbalLockTheMatrixRoundTrips) {
  for (double offset : {0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-3}) {
    for (double sign : {-1.0, 1.0}) {
      const double p = sign * (kPi / 2 - offset);
      for (double t : {-2.0, 0.0, 0.7}) {
        for (double k : {-1.0, 0.0, 2.5}) {
          const Eigen::Matrix3d m = RotationFromAngles(t, p, k);
          const AttitudeAngles a = AnglesFromRotation(m);
          EXPECT_TRUE(std::isfinite(a.theta) && std::isfinite(a.phi) && std::isfinite(a.kappa));
          EXPECT_LT((RotationFromAngles(a) - m).cwiseAbs().maxCoeff(), 1e-9)
              << "offset " << offset << " t " << t << " p " << p << " k " << k;
          EXPECT_NEAR(a.phi, p, 1e-6);
        }
      }
    }
  }
  // Exactly locked: theta is set to zero and kappa carries the whole turn.
  const AttitudeAngles locked = AnglesFromRotation(RotationFromAngles(0.0, kPi / 2, 0.4));
  EXPECT_NEAR(locked.phi, kPi / 2, 1e-12);
}

TEST(Rotation, QuaternionAndOpticalFrameRoundTrip) {
  const AttitudeAngles a{0.4, -1.1, 0.25};
  const AttitudeAngles back = AnglesFromQuaternion(QuaternionFromAngles(a));
  EXPECT_NEAR(back.theta, a.theta, 1e-12);
  EXPECT_NEAR(back.phi, a.phi, 1e-12);
  EXPECT_NEAR(back.kappa, a.kappa, 1e-12);
  const AttitudeAngles from_tf = AnglesFromSiteFromOptical(SiteFromOpticalFromAngles(a));
  EXPECT_NEAR(from_tf.theta, a.theta, 1e-12);
  EXPECT_NEAR(from_tf.phi, a.phi, 1e-12);
  EXPECT_NEAR(from_tf.kappa, a.kappa, 1e-12);
}

TEST(Rotation, NadirOpticalFrameLooksDown) {
  // REP 103: the optical z axis is the viewing direction. A nadir camera
  // (all angles zero) looks along site -z; its optical x is site +x and its
  // optical y (image down) is site -y (image up is north).
  const Eigen::Matrix3d site_from_optical =
      SiteFromOpticalFromAngles(AttitudeAngles{}).toRotationMatrix();
  EXPECT_TRUE(site_from_optical.col(2).isApprox(Eigen::Vector3d(0, 0, -1), kTol));
  EXPECT_TRUE(site_from_optical.col(0).isApprox(Eigen::Vector3d(1, 0, 0), kTol));
  EXPECT_TRUE(site_from_optical.col(1).isApprox(Eigen::Vector3d(0, -1, 0), kTol));
}

}  // namespace
}  // namespace camera
}  // namespace slope_monitor
