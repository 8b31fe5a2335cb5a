// replay.launch site:=config/sites/demo.yaml: a tf listener started `late`
// seconds after playback began sees `site` (latched /tf_static), and the
// deformation estimator, which reads the site file, is up.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "test_node.h"

namespace slope_monitor {
namespace {

using rostest_node::Param;
using rostest_node::WaitFor;

bool Advertised(const std::string& topic) {
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  for (const ros::master::TopicInfo& t : topics)
    if (t.name == topic) return true;
  return false;
}

TEST(SiteTfStatic, ALateListenerSeesTheSiteFrame) {
  ros::NodeHandle pnh("~");
  const double late = Param(pnh, "late", 12.0);
  const double wait = Param(pnh, "wait", 5.0);
  // Playback has begun once the bag's clock runs.
  ASSERT_TRUE(WaitFor([] { return !ros::Time::now().isZero(); }, 60.0))
      << "no /clock from rosbag play";
  ros::WallDuration(late).sleep();
  // Only now a listener starts, long after the bag's single /tf_static message was played.
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  // rx1_antenna comes from the bag only (nothing in the graph publishes it).
  for (const char* frame : {"rx1_antenna", "rx5_antenna", "fixed_cam_1_optical"}) {
    EXPECT_TRUE(WaitFor([&] { return buffer.canTransform("site", frame, ros::Time(0)); }, wait))
        << "site -> " << frame << " not known to a listener started " << late
        << " s after playback began";
  }
  EXPECT_TRUE(buffer._frameExists("site")) << buffer.allFramesAsString();
  // The nodes read the site file: the estimator advertises its outputs only
  // when every parameter (site_file among them) was accepted.
  EXPECT_TRUE(WaitFor([] { return Advertised("/deformation_estimator/deformation"); }, wait));
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "site_tf_static_test");
}
