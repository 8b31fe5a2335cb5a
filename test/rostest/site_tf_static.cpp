// replay.launch site:=config/sites/demo.yaml: a tf listener started `late`
// seconds after playback began sees `site` (latched /tf_static), and the
// deformation estimator, which reads the site file, is up.
#include <mutex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <ros/service.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "slope_monitor/AdjustmentSolution.h"

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

// Every solution of the bundle adjuster, from the start (latched: the latest
// also reaches a late subscriber).
std::vector<AdjustmentSolution> solutions;
std::vector<double> received;  // [s] bag clock when each came
std::mutex solutions_mutex;
ros::Subscriber solution_sub;
double clock_started = 0.0;  // [s] bag clock when the test first saw it run

void OnSolution(const AdjustmentSolutionConstPtr& m) {
  std::lock_guard<std::mutex> lock(solutions_mutex);
  solutions.push_back(*m);
  received.push_back(ros::Time::now().toSec());
}

TEST(SiteTfStatic, ALateListenerSeesTheSiteFrame) {
  ros::NodeHandle nh;
  solution_sub = nh.subscribe("/bundle_adjuster/solution", 10, &OnSolution);
  ros::NodeHandle pnh("~");
  const double late = Param(pnh, "late", 12.0);
  const double wait = Param(pnh, "wait", 5.0);
  // Playback has begun once the bag's clock runs.
  ASSERT_TRUE(WaitFor([] { return !ros::Time::now().isZero(); }, 60.0))
      << "no /clock from rosbag play";
  clock_started = ros::Time::now().toSec();
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

// Issue 18: every node's parameters sit under its own name, once
// (/deformation_estimator/threshold_alarm, not
// /deformation_estimator/deformation_estimator/threshold_alarm), and its
// outputs and services beside them.
TEST(SiteTfStatic, ParametersSitUnderTheNodeNameOnce) {
  ASSERT_TRUE(WaitFor([] { return Advertised("/deformation_estimator/deformation"); }, 60.0));
  for (const char* key :
       {"/deformation_estimator/threshold_alarm", "/deformation_estimator/site_file",
        "/bundle_adjuster/epoch_wait", "/bundle_adjuster/site_file",
        "/radio/radio_phase_solver/site_file", "/dense/dense_matcher/report_dir"})
    EXPECT_TRUE(ros::param::has(key)) << key;
  for (const char* doubled : {"/deformation_estimator/deformation_estimator",
                              "/bundle_adjuster/bundle_adjuster"})
    EXPECT_FALSE(ros::param::has(doubled)) << doubled;
  for (const char* service : {"/bundle_adjuster/run_adjustment", "/bundle_adjuster/resect_camera",
                              "/deformation_estimator/export_report"})
    EXPECT_TRUE(ros::service::waitForService(service, ros::Duration(10.0))) << service;
  EXPECT_TRUE(WaitFor([] { return Advertised("/bundle_adjuster/solution"); }, 10.0));
}

// Issue 18: the cameras come from the site file (demo.yaml lists fixed_cam_1,
// fixed_cam_2 and a uav): one centroider serves every camera with targets, and
// the bundle adjuster waits only for those the bag has (fixed_cam_1; the others
// never send): both epochs are solved, the first while the bag still plays.
TEST(SiteTfStatic, TheSiteFilesCamerasAreServedAndEveryEpochSolved) {
  for (const char* topic : {"/fixed_cam_1/targets", "/fixed_cam_2/targets", "/uav/targets"})
    EXPECT_TRUE(WaitFor([&] { return Advertised(topic); }, 10.0)) << topic;
  ASSERT_TRUE(WaitFor(
      [] {
        std::lock_guard<std::mutex> lock(solutions_mutex);
        return solutions.size() >= 2;
      },
      60.0))
      << "fewer than 2 adjustment solutions";
  std::lock_guard<std::mutex> lock(solutions_mutex);
  EXPECT_EQ(solutions.size(), 2u);
  EXPECT_NE(solutions[0].epoch, solutions[1].epoch);
  // The first epoch was not held for the absent cameras until the end of the
  // bag (the next epoch's markers come 60 s of bag time later).
  EXPECT_LT(received[0], clock_started + 30.0)
      << "epoch " << solutions[0].epoch << " solved " << received[0] - clock_started
      << " s of bag time after the replay began";
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "site_tf_static_test");
}
