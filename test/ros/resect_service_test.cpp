// The bundle adjuster's service resect_camera through its adapter
// (ros/resect_service.h), as a client's request and response: a simulated
// camera resected from 15 surveyed points (truth: the points projected by the
// true camera, picks with 0.3 px noise); the answer's pose, angles and c
// against the truth within 3 sigma; bad requests answered with the field named.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "../core/adjustment/resect_scenario.h"
#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/resect_service.h"

namespace slope_monitor {
namespace {

// 15 points on the slope 150-200 m from the camera (test/core/adjustment/
// resect_scenario.h), picked with 0.3 px noise, as the service's request.
slope_monitor::ResectCamera::Request ResectServiceRequest() {
  const std::vector<io::PickedPoint> points = resect_scenario::Survey(
      resect_scenario::Camera(16.0), resect_scenario::TruePose(), 15, 0.0, 0.3, 11);
  slope_monitor::ResectCamera::Request r;
  r.camera_info =
      ros_adapters::ToMsg(resect_scenario::Camera(15.0).ToCameraInfo());  // nominal c 6 % off
  for (const io::PickedPoint& p : points) {
    geometry_msgs::Point x;
    x.x = p.xyz.x();
    x.y = p.xyz.y();
    x.z = p.xyz.z();
    r.points.push_back(x);
    r.u.push_back(p.pixel.x());
    r.v.push_back(p.pixel.y());
    r.ids.push_back(p.id);
  }
  r.pixel_sigma = 0.3;
  return r;
}

TEST(ResectService, AnswersThePoseAndFocalOfTheTruthWithinThreeSigma) {
  slope_monitor::ResectCamera::Response res;
  ros_adapters::Resect(ResectServiceRequest(), &res);
  ASSERT_TRUE(res.success) << res.message;
  const camera::ExteriorOrientation truth = resect_scenario::TruePose();
  const auto sigma = [&](int k) { return std::sqrt(res.camera.pose_covariance[7 * k]); };
  EXPECT_LT(std::abs(res.camera.site_from_optical.position.x - truth.position.x()), 3 * sigma(0));
  EXPECT_LT(std::abs(res.camera.site_from_optical.position.y - truth.position.y()), 3 * sigma(1));
  EXPECT_LT(std::abs(res.camera.site_from_optical.position.z - truth.position.z()), 3 * sigma(2));
  EXPECT_LT(std::abs(res.camera.theta - truth.angles.theta), 3 * sigma(3));
  EXPECT_LT(std::abs(res.camera.phi - truth.angles.phi), 3 * sigma(4));
  EXPECT_LT(std::abs(res.camera.kappa - truth.angles.kappa), 3 * sigma(5));
  ASSERT_EQ(res.camera.interior_sigma.size(), static_cast<size_t>(camera::kNumInterior));
  EXPECT_GT(res.camera.interior_sigma[camera::kC], 0.0);  // c estimated, the rest held
  EXPECT_EQ(res.camera.interior_sigma[camera::kK1], 0.0);
  // From a camera_info the interior is in pixels (pixel size 1): c = 16 mm / 4 um.
  EXPECT_LT(std::abs(res.camera.principal_distance - 4000.0),
            3 * res.camera.interior_sigma[camera::kC]);
  EXPECT_LT(res.camera.interior_sigma[camera::kC], 40.0);  // c to 1 %
  // The adjusted camera_info: fx = c.
  EXPECT_NEAR(res.camera_info.K[0], res.camera.principal_distance, 1e-6);
  // RMS of 15 picks with 0.3 px noise in each coordinate: about 0.3 * sqrt(2).
  EXPECT_GT(res.rms_px, 0.2);
  EXPECT_LT(res.rms_px, 0.6);
  EXPECT_EQ(res.residual_u.size(), 15u);
  EXPECT_TRUE(res.snooping_failed.empty());
}

TEST(ResectService, BadRequestsAreAnsweredNamingTheField) {
  slope_monitor::ResectCamera::Response res;
  auto r = ResectServiceRequest();
  r.u.pop_back();
  ros_adapters::Resect(r, &res);
  EXPECT_FALSE(res.success);
  EXPECT_NE(res.message.find("u (14)"), std::string::npos) << res.message;

  r = ResectServiceRequest();
  r.points.resize(3);
  r.u.resize(3);
  r.v.resize(3);
  r.ids.resize(3);
  ros_adapters::Resect(r, &res);
  EXPECT_FALSE(res.success);
  EXPECT_NE(res.message.find("4"), std::string::npos) << res.message;

  r = ResectServiceRequest();
  r.free = {"c", "focal"};
  ros_adapters::Resect(r, &res);
  EXPECT_FALSE(res.success);
  EXPECT_NE(res.message.find("focal"), std::string::npos) << res.message;

  r = ResectServiceRequest();
  r.camera_info.K[0] = 0.0;
  ros_adapters::Resect(r, &res);
  EXPECT_FALSE(res.success);
  EXPECT_NE(res.message.find("camera_info"), std::string::npos) << res.message;
}

}  // namespace
}  // namespace slope_monitor
