// CameraInfo <-> collinearity model through the ROS adapters.
#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace {

TEST(CameraInfoConversion, RoundTripThroughTheMessage) {
  std::array<double, camera::kNumInterior> p{};
  p[camera::kC] = 16.0;
  p[camera::kX0] = 0.02;
  p[camera::kK1] = -1e-4;
  p[camera::kP1] = 2e-5;
  const camera::CameraModel cam(camera::Sensor{1280, 960, 0.00345}, camera::DistortionModel::kBrown,
                                p);
  const sensor_msgs::CameraInfo msg = ros_adapters::ToMsg(cam.ToCameraInfo());
  EXPECT_EQ(msg.width, 1280u);
  EXPECT_EQ(msg.distortion_model, "plumb_bob");
  // fx = c / pixel size, cx = (W - 1) / 2 + x0 / pixel size.
  EXPECT_NEAR(msg.K[0], 16.0 / 0.00345, 1e-9);
  EXPECT_NEAR(msg.K[2], 639.5 + 0.02 / 0.00345, 1e-9);
  const camera::CameraModel back = ros_adapters::CameraModelFromCameraInfo(msg, 0.00345);
  for (int i = 0; i < camera::kNumInterior; ++i) {
    EXPECT_NEAR(back.interior()[i], cam.interior()[i], 1e-12) << camera::InteriorNames()[i];
  }
}

TEST(CameraInfoConversion, UnrepresentableModelIsNamed) {
  sensor_msgs::CameraInfo msg;
  msg.width = 640;
  msg.height = 480;
  msg.distortion_model = "equidistant";
  msg.D = {0.1, 0.0, 0.0, 0.0};
  msg.K = {500, 0, 320, 0, 500, 240, 0, 0, 1};
  try {
    ros_adapters::CameraModelFromCameraInfo(msg, 1.0);
    FAIL() << "accepted equidistant";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("equidistant"), std::string::npos);
  }
}

TEST(CameraInfoConversion, PoseConversionRoundTrip) {
  const Rigid3 t(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
                 Eigen::Vector3d(1, -2, 3));
  const Rigid3 back = ros_adapters::FromPose(ros_adapters::ToPose(t));
  EXPECT_TRUE(back.rotation.isApprox(t.rotation, 1e-15));
  EXPECT_TRUE(back.translation.isApprox(t.translation, 1e-15));
}

}  // namespace
}  // namespace slope_monitor
