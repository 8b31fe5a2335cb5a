// Issue 36: the steps the nodelets and process_bag share (ros/radio_step.h,
// ros/adjuster_step.h, ros/target_centroider_step.h): which radio receiver a
// topic is, which cameras a replay's epochs wait for, and the centroider's
// targets, poses, pixel size and photo handling -- decided by one function
// for both.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/adjuster_step.h"
#include "slope_monitor/ros/radio_step.h"
#include "slope_monitor/ros/target_centroider_step.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

using Strings = std::vector<std::string>;

TEST(RadioStep, ReceiverOfTopicIsTheIdBetweenRadioAndSamples) {
  EXPECT_EQ(RadioReceiverOfTopic("/radio/rx_north/samples"), "rx_north");
  EXPECT_EQ(RadioReceiverOfTopic("/radio/samples"), "");
  EXPECT_EQ(RadioReceiverOfTopic("/other/rx_north/samples"), "");
  EXPECT_EQ(RadioReceiverOfTopic("/radio/rx_north/phase"), "");
}

TEST(RadioStep, RefusesParametersWithoutANetwork) {
  EXPECT_THROW(RadioStep(RadioParameters{}), ConfigError);
}

AdjusterParameters SiteCameras() {
  AdjusterParameters p;
  p.cameras_from_site = true;
  p.collector.cameras = {"north_ridge", "gully_2", "drone"};
  return p;
}

TEST(ReplayCameras, KeepsTheSiteCamerasTheReplayHasAndNamesTheOthers) {
  std::vector<LogLine> log;
  const Strings kept = ReplayCameras(
      SiteCameras(), [](const std::string& c) { return c != "drone"; }, &log);
  EXPECT_EQ(kept, (Strings{"north_ridge", "gully_2"}));
  ASSERT_EQ(log.size(), 1u);
  EXPECT_NE(log[0].text.find("'drone'"), std::string::npos) << log[0].text;
}

TEST(ReplayCameras, KeepsAllWhenTheReplayHasNoneOfThem) {
  std::vector<LogLine> log;
  EXPECT_EQ(ReplayCameras(
                SiteCameras(), [](const std::string&) { return false; }, &log),
            SiteCameras().collector.cameras);
  EXPECT_TRUE(log.empty());
}

TEST(ReplayCameras, LeavesCamerasThatAreNotTheSiteFilesAlone) {
  AdjusterParameters p = SiteCameras();
  p.cameras_from_site = false;
  std::vector<LogLine> log;
  EXPECT_EQ(ReplayCameras(
                p, [](const std::string& c) { return c == "drone"; }, &log),
            p.collector.cameras);
}

// ---- the target centroider's step (nodelet and process_bag).

geometry_msgs::TransformStamped SiteToCamera(const std::string& camera, double x, double stamp) {
  geometry_msgs::TransformStamped t;
  t.header.frame_id = "site";
  t.header.stamp = ros::Time(stamp);
  t.child_frame_id = camera;
  t.transform.translation.x = x;
  t.transform.rotation.w = 1.0;
  return t;
}

tf2_msgs::TFMessage Tf(const geometry_msgs::TransformStamped& t) {
  tf2_msgs::TFMessage m;
  m.transforms.push_back(t);
  return m;
}

// A 4 x 3 mono8 photo of `camera`'s optical frame at t = 100 s, and its
// camera_info (calibrated: K[0] = 1000).
sensor_msgs::Image Photo(const std::string& frame) {
  sensor_msgs::Image image;
  image.header.frame_id = frame;
  image.header.stamp = ros::Time(100.0);
  image.width = 4;
  image.height = 3;
  image.encoding = "mono8";
  image.step = 4;
  image.data.assign(12, 0);
  return image;
}

sensor_msgs::CameraInfo Calibrated() {
  sensor_msgs::CameraInfo info;
  info.width = 4;
  info.height = 3;
  info.K[0] = info.K[4] = 1000.0;
  return info;
}

TEST(CameraPoses, KeepsTheFirstStaticPoseOfAFrameAndEveryTfPose) {
  CameraPoses poses(1e6);
  std::vector<std::string> problems;
  poses.Add(Tf(SiteToCamera("cam_optical", 1.0, 0.0)), true, &problems);
  // The adjuster's adjusted pose republished on /tf_static: not taken.
  poses.Add(Tf(SiteToCamera("cam_optical", 2.0, 0.0)), true, &problems);
  EXPECT_EQ(
      poses.buffer().lookupTransform("site", "cam_optical", ros::Time(0)).transform.translation.x,
      1.0);
  poses.Add(Tf(SiteToCamera("uav_optical", 3.0, 10.0)), false, &problems);
  poses.Add(Tf(SiteToCamera("uav_optical", 5.0, 20.0)), false, &problems);
  EXPECT_DOUBLE_EQ(poses.buffer()
                       .lookupTransform("site", "uav_optical", ros::Time(15.0))
                       .transform.translation.x,
                   4.0);  // interpolated between the two /tf poses
  EXPECT_TRUE(problems.empty());
}

TEST(TargetCentroiderStep, PixelSizeIsTheSiteCamerasElseTheNodes) {
  targets::NodeOptions node;
  node.pixel_size = 0.0048;
  io::SiteCamera camera;
  EXPECT_EQ(CameraPixelSize(node, nullptr), 0.0048);
  EXPECT_EQ(CameraPixelSize(node, &camera), 0.0048);  // 0: not given
  camera.pixel_size = 0.1;
  EXPECT_EQ(CameraPixelSize(node, &camera), 0.1);
}

TEST(TargetCentroiderStep, TheSitesTargetsWinOverTheTargetList) {
  targets::NodeOptions node;
  node.target_list = "/nonexistent/targets.yaml";  // not read when the site lists targets
  io::SiteFile site;
  site.targets = io::TargetList();
  io::TargetSpec spec;
  spec.id = 7;
  site.targets->Add(spec);
  const io::TargetList list = CentroiderTargets(node, &site);
  ASSERT_EQ(list.targets().size(), 1u);
  EXPECT_EQ(list.targets()[0].Key(), "tag36h11/7");
  EXPECT_THROW(CentroiderTargets(node, nullptr), Error);  // IoError naming the missing file
  node.target_list.clear();
  EXPECT_TRUE(CentroiderTargets(node, nullptr).targets().empty());
}

TEST(TargetCentroiderStep, WithoutTargetsEachPhotoGetsItsEmptyListAndNoPose) {
  TargetCentroiderStep step("drone", 0.0048, TargetCentroiderParameters(), std::nullopt,
                            "/drone/camera/image_raw");
  CameraPoses poses(1e6);
  std::vector<std::string> problems;
  poses.Add(Tf(SiteToCamera("drone_optical", 1.0, 0.0)), true, &problems);
  const sensor_msgs::Image image = Photo("drone_optical");
  EXPECT_FALSE(step.Pose(poses.buffer(), image, Calibrated()));  // nothing to identify
  const CentroidedImage c = step.Centroid(image, Calibrated(), std::nullopt);
  EXPECT_EQ(c.targets.camera_name, "drone");
  EXPECT_EQ(c.targets.header.stamp, image.header.stamp);
  EXPECT_EQ(c.targets.image_width, 4u);
  EXPECT_EQ(c.targets.image_height, 3u);
  EXPECT_TRUE(c.targets.observations.empty());
  step.Count(c);
  EXPECT_EQ(step.counts().frames, 1);
}

TEST(TargetCentroiderStep, PoseOnlyForACalibratedPhotoWithATransform) {
  TargetCentroiderStep step("cam", 0.0048, TargetCentroiderParameters(), io::TargetList(),
                            "/cam/camera/image_raw");
  CameraPoses poses(1e6);
  std::vector<std::string> problems;
  poses.Add(Tf(SiteToCamera("cam_optical", 1.5, 0.0)), true, &problems);
  const auto pose = step.Pose(poses.buffer(), Photo("cam_optical"), Calibrated());
  ASSERT_TRUE(pose);
  EXPECT_EQ(pose->translation().x(), 1.5);
  EXPECT_FALSE(step.Pose(poses.buffer(), Photo("cam_optical"), sensor_msgs::CameraInfo()));
  EXPECT_FALSE(step.Pose(poses.buffer(), Photo("other_optical"), Calibrated()));
}

TEST(TargetCentroiderStep, ADroppedPhotoIsCountedAndNamedWithItsTopicAndStamp) {
  TargetCentroiderStep step("cam", 0.0048, TargetCentroiderParameters(), io::TargetList(),
                            "/cam/camera/image_raw");
  sensor_msgs::Image image = Photo("cam_optical");
  image.encoding = "no_such_encoding";
  std::string line;
  try {
    step.Centroid(image, Calibrated(), std::nullopt);
    ADD_FAILURE() << "a photo of an unknown encoding was centroided";
  } catch (const std::exception& e) {
    line = step.Dropped(image.header, e.what());
  }
  EXPECT_EQ(line.rfind("dropped image (topic /cam/camera/image_raw, stamp 100.000): ", 0), 0u)
      << line;
  EXPECT_EQ(step.counts().errors, 1);
  EXPECT_EQ(step.counts().frames, 0);
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
