// CameraInfo <-> collinearity model through the ROS adapters.
#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/image_limits.h"
#include "slope_monitor/ros/sequence_conversions.h"

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

// Image messages whose header claims more than the pixel budget, or does not
// describe the data, are refused before cv_bridge touches them (issue 38);
// the conversions the nodelets use check it themselves.
TEST(ImageMessageLimits, ForgedHeadersAreRefusedBeforeConversion) {
  sensor_msgs::Image good;
  good.width = 64;
  good.height = 48;
  good.encoding = "mono8";
  good.step = 64;
  good.data.assign(64 * 48, 128);
  EXPECT_NO_THROW(ros_adapters::CheckImageMessage(good));
  EXPECT_EQ(ros_adapters::ImageForMatching(boost::make_shared<sensor_msgs::Image>(good)).cols, 64);
  const auto refused = [](const sensor_msgs::Image& m, const std::string& want) {
    try {
      ros_adapters::CheckImageMessage(m);
      ADD_FAILURE() << "accepted: " << want;
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
    try {
      ros_adapters::ImageForMatching(boost::make_shared<sensor_msgs::Image>(m));
      ADD_FAILURE() << "converted: " << want;
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
  };
  sensor_msgs::Image huge = good;  // 20000 x 20000 claimed, 3072 bytes held
  huge.width = huge.height = huge.step = 20000;
  refused(huge, "image 20000 x 20000 px (400.0 MP), more than max_megapixels 100");
  sensor_msgs::Image short_data = good;
  short_data.data.resize(1000);
  refused(short_data, "step 64 x height 48 = 3072 bytes, but the message holds 1000");
  sensor_msgs::Image short_step = good;  // rgb8 rows of 64 px are 192 bytes
  short_step.encoding = "rgb8";
  refused(short_step, "step 64 bytes is shorter than a row (192 bytes)");
  ros_adapters::ImageMessageLimits small;
  small.max_megapixels = 0.001;  // 1000 px
  EXPECT_THROW(ros_adapters::CheckImageMessage(good, small), InvalidArgument);
  EXPECT_EQ(ros_adapters::MaxImageMessageBytes(small), 8000u + (1u << 20));
}

}  // namespace
}  // namespace slope_monitor
