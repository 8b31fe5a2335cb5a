// Issue 36: the steps the nodelets and process_bag share (ros/radio_step.h,
// ros/adjuster_step.h): which radio receiver a topic is, and which cameras a
// replay's epochs wait for -- decided by one function for both.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/adjuster_step.h"
#include "slope_monitor/ros/radio_step.h"

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

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
