// capture::SiteFromOpticalNadir: the nadir attitude of a photo flown at an
// autopilot heading, checked at headings whose axes are written by hand.
#include <gtest/gtest.h>

#include "slope_monitor/core/capture/photo_attitude.h"

namespace slope_monitor {
namespace capture {
namespace {

// Image right, image down and the viewing direction in site (x east, y north, z up).
void ExpectAxes(double yaw_deg, const Eigen::Vector3d& right, const Eigen::Vector3d& down) {
  const Eigen::Matrix3d r = SiteFromOpticalNadir(yaw_deg).toRotationMatrix();
  EXPECT_LT((r.col(0) - right).norm(), 1e-12) << "heading " << yaw_deg;
  EXPECT_LT((r.col(1) - down).norm(), 1e-12) << "heading " << yaw_deg;
  EXPECT_LT((r.col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12) << "heading " << yaw_deg;
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(SiteFromOpticalNadir, TopOfTheImageAlongTheHeading) {
  ExpectAxes(0.0, {1, 0, 0}, {0, -1, 0});    // north: right is east, image down is south
  ExpectAxes(90.0, {0, -1, 0}, {-1, 0, 0});  // east: right is south, image down is west
  ExpectAxes(180.0, {-1, 0, 0}, {0, 1, 0});  // south: right is west
  ExpectAxes(-90.0, {0, 1, 0}, {1, 0, 0});   // west: right is north
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
