// Bad input, a bag missing a topic: the survey has no radio samples at all
// (test/rostest/estimator_no_radio.test.in). The graph must still give the
// target-based deformation estimate: every monitoring target in the stored
// history, within k sigma of the simulator's truth, measured by targets
// only, and no radio point.
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <ros/ros.h>

#include <gtest/gtest.h>

#include "slope_monitor/core/evaluation/deformation_truth.h"
#include "slope_monitor/core/sim/truth.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

using rostest_node::Param;

TEST(EstimatorNoRadio, TargetEstimatesWithoutTheRadioTopics) {
  ros::NodeHandle pnh("~");
  std::string bag_path, truth_path, database;
  ASSERT_TRUE(pnh.getParam("bag", bag_path));
  ASSERT_TRUE(pnh.getParam("truth_file", truth_path));
  ASSERT_TRUE(pnh.getParam("database", database));
  const double timeout = Param(pnh, "timeout", 300.0);       // [s wall]
  const double settle = Param(pnh, "settle", 15.0);          // [s wall]
  const double end_margin = Param(pnh, "end_margin", 60.0);  // [s simulated]
  const double max_nees = Param(pnh, "max_normalised_error", 3.0);
  const int min_monitoring = static_cast<int>(Param(pnh, "min_monitoring_points", 6));

  ros::Time bag_end;
  int radio_connections = 0;
  {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    bag_end = view.getEndTime();
    for (const rosbag::ConnectionInfo* c : view.getConnections())
      if (c->topic.rfind("/radio/", 0) == 0) ++radio_connections;
  }
  ASSERT_EQ(radio_connections, 0) << "the bag of this test must not have radio topics";
  ASSERT_TRUE(rostest_node::WaitForClock(bag_end - ros::Duration(end_margin), timeout))
      << "the bag did not finish playing";
  ros::WallDuration(settle).sleep();

  const sim::SurveyTruth truth = sim::SurveyTruth::Load(truth_path);
  const evaluation::DeformationEvaluation e = evaluation::EvaluateHistory(database, truth);
  std::cout << evaluation::FormatTable(e);
  int monitoring = 0;
  for (const auto& p : e.points) {
    EXPECT_NE(p.role, "radio") << p.id;
    for (const auto& [source, count] : p.measurements)
      EXPECT_EQ(evaluation::SourceName(source), "target") << p.id << ": " << count << " measurement(s)";
    if (p.role == "monitoring") {
      ++monitoring;
      EXPECT_LE(p.NormalisedError(), max_nees) << p.id << ": error " << p.Error().transpose() * 1e3 << " mm, sigma "
                                               << p.Sigma() * 1e3 << " mm";
    }
  }
  EXPECT_GE(monitoring, min_monitoring) << "monitoring targets in the estimate without radio";
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "estimator_no_radio_test");
  ros::NodeHandle nh;
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
