// The notification hook through the deformation estimator node: one hook run
// per published alert-level change, with that change's JSON; and the live
// report timer (report_interval) writing the reports while the node runs.
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>

#include "../core/deformation/hook_json.h"
#include "../core/deformation/test_scenario.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/SlopeDeformation.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

using deformation::testing::kDay;
using deformation::testing::kT0;
using rostest_node::Param;
using rostest_node::WaitFor;
constexpr double kMmPerDay = 1e-3 / kDay;

using hook_json::Field;
using hook_json::Lines;

TEST(EstimatorHook, OneRunPerPublishedLevelChange) {
  ros::NodeHandle nh, pnh("~");
  std::string hook_out;
  ASSERT_TRUE(pnh.getParam("hook_out", hook_out));
  std::string report_csv;
  ASSERT_TRUE(pnh.getParam("report_csv", report_csv));
  const double timeout = Param(pnh, "timeout", 60.0);

  // What the estimator publishes: each point's level, message by message.
  std::mutex mutex;
  hook_json::LevelChanges changes;
  double last_stamp = 0.0;
  ros::Subscriber sub = nh.subscribe<slope_monitor::SlopeDeformation>(
      "/deformation_estimator/deformation", 5000,
      [&](const slope_monitor::SlopeDeformation::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(mutex);
        changes.Add(*m);
        last_stamp = m->header.stamp.toSec();
      });
  ros::Publisher pub = nh.advertise<slope_monitor::PointDisplacementArray>(
      "/deformation_estimator/displacements", 5000);
  ASSERT_TRUE(
      WaitFor([&] { return pub.getNumSubscribers() > 0 && sub.getNumPublishers() > 0; }, timeout));

  // Three points on a body accelerating to failure at t0 + 6 d (6 mm/day at
  // t0, 144 mm/day at t0 + 5.75 d) and three on stable ground, every 30 min.
  const std::vector<std::string> ids = {"body1", "body2", "body3", "stable1", "stable2", "stable3"};
  std::vector<deformation::testing::Motion> motions(6);
  for (int i = 0; i < 3; ++i) {
    motions[i].v0 = 6 * kMmPerDay;
    motions[i].accelerating = true;
    motions[i].failure_time = kT0 + 6 * kDay;
  }
  deformation::testing::SourceSpec radio;
  radio.sigma = Eigen::Vector3d(0.004, 0.004, 0.004);
  radio.seed = 21;
  const auto batches = deformation::testing::MakeBatches(radio, ids, motions, kT0 + 5.75 * kDay);
  for (const deformation::Batch& b : batches) {
    slope_monitor::PointDisplacementArray msg;
    msg.header.stamp.fromSec(b.stamp);
    msg.header.frame_id = "site";
    msg.epoch = b.epoch;
    for (const deformation::Measurement& m : b.measurements)
      msg.displacements.push_back(ros_adapters::MakePointDisplacement(
          m.point_id, slope_monitor::PointDisplacement::SOURCE_RADIO, m.source_name,
          m.reference_stamp, ros::Time(m.stamp), m.reference_position, m.displacement,
          m.covariance));
    pub.publish(msg);
    // Lock-step: the next batch only after the estimator published this one
    // (its outgoing queue is short; nothing may be dropped between us).
    ASSERT_TRUE(WaitFor(
        [&] {
          std::lock_guard<std::mutex> lock(mutex);
          return last_stamp >= b.stamp - 1e-3;
        },
        timeout))
        << "the estimator did not publish the batch at " << b.stamp;
  }
  std::vector<hook_json::LevelChange> expected;
  {
    std::lock_guard<std::mutex> lock(mutex);
    expected = changes.changes();
  }
  // The body accelerates to 144 mm/day: its points raise alerts (with the
  // node's defaults measured: body2 and body3 none -> watch -> warning in the
  // last half day); stable ground never changes.
  ASSERT_GE(expected.size(), 2u);
  ASSERT_TRUE(WaitFor([&] { return Lines(hook_out).size() >= expected.size(); }, timeout))
      << Lines(hook_out).size() << " hook runs for " << expected.size() << " level changes";
  ros::WallDuration(1.0).sleep();  // nothing more arrives
  const std::vector<std::string> got = Lines(hook_out);
  ASSERT_EQ(got.size(), expected.size());
  for (size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(Field(got[k], "site"), "hook_test");
    EXPECT_EQ(Field(got[k], "point"), expected[k].point) << got[k];
    EXPECT_EQ(Field(got[k], "from"), expected[k].from) << got[k];
    EXPECT_EQ(Field(got[k], "level"), expected[k].to) << got[k];
    EXPECT_NEAR(std::stod(Field(got[k], "speed_mm_per_day")), expected[k].speed_mm_per_day, 1e-3)
        << got[k];
    EXPECT_EQ(Field(got[k], "point").rfind("body", 0), 0u) << got[k];
  }
  // The report timer (report_interval 1 s; report_on_alert_change off, the
  // node still running): the CSV report holds the estimate at the last batch.
  const std::string last_time = "," + Utc(batches.back().stamp) + ",";
  const auto report_has_last_batch = [&] {
    std::ifstream in(report_csv);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return text.find(last_time) != std::string::npos;
  };
  EXPECT_TRUE(WaitFor(report_has_last_batch, 10.0))
      << report_csv << " does not hold the estimate at " << last_time;
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "estimator_hook_test");
}
