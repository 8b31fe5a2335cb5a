// Plays a simulated survey bag through the whole graph (replay.launch, with
// --clock) and checks the deformation estimator's stored history against the
// simulator's truth. Expected values and tolerances come in as parameters
// (test/rostest/full_graph_replay.test).
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <ros/ros.h>

#include <gtest/gtest.h>

#include "slope_monitor/core/evaluation/deformation_truth.h"

namespace slope_monitor {
namespace {

double Param(const ros::NodeHandle& nh, const std::string& key, double fallback) {
  double v = fallback;
  nh.param(key, v, fallback);
  return v;
}

TEST(FullGraphReplay, FusedDeformationMatchesTruth) {
  ros::NodeHandle pnh("~");
  std::string bag_path, truth_path, database;
  ASSERT_TRUE(pnh.getParam("bag", bag_path)) << "~bag is required";
  ASSERT_TRUE(pnh.getParam("truth_file", truth_path)) << "~truth_file is required";
  ASSERT_TRUE(pnh.getParam("database", database)) << "~database is required";
  const double timeout = Param(pnh, "timeout", 600.0);          // [s wall]
  const double settle = Param(pnh, "settle", 15.0);             // [s wall] after the bag's end
  // rosbag play publishes /clock at a fixed wall rate, so the last clock it
  // sends may fall a few (simulated) seconds short of the last message.
  const double end_margin = Param(pnh, "end_margin", 60.0);     // [s simulated]
  const double max_rms = Param(pnh, "max_monitoring_rms", 0.005);   // [m]
  const double max_nees = Param(pnh, "max_normalised_error", 3.0);  // [sigma]
  const int min_alert_moving = static_cast<int>(Param(pnh, "min_alert_moving", 1));
  const int max_alert_stable = static_cast<int>(Param(pnh, "max_alert_stable", 0));
  const double forecast_k = Param(pnh, "forecast_sigma_factor", 3.0);
  const double min_monitoring_points = Param(pnh, "min_monitoring_points", 1);
  const double max_radio_error = Param(pnh, "max_radio_error", 0.005);    // [m] each transmitter, latest estimate
  const double min_radio_points = Param(pnh, "min_radio_points", 5);

  ros::Time bag_end;
  {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    bag_end = view.getEndTime();
  }
  // Wait for the simulated clock to reach the end of the bag, then let the
  // graph finish what it has queued.
  const ros::WallTime start = ros::WallTime::now();
  while (ros::ok() && (ros::Time::now() < bag_end - ros::Duration(end_margin))) {
    ASSERT_LT((ros::WallTime::now() - start).toSec(), timeout)
        << "the bag did not finish playing; clock at " << ros::Time::now() << ", end " << bag_end;
    ros::WallDuration(0.5).sleep();
  }
  ros::WallDuration(settle).sleep();

  const sim::SurveyTruth truth = sim::SurveyTruth::Load(truth_path);
  const evaluation::DeformationEvaluation e = evaluation::EvaluateHistory(database, truth);
  std::cout << evaluation::FormatTable(e);

  int monitoring = 0, radio = 0;
  double sum2 = 0.0;
  for (const auto& p : e.points) {
    const bool moving = p.truth.norm() > 0.01;
    if (p.role == "monitoring") {
      ++monitoring;
      sum2 += p.Error().squaredNorm();
      EXPECT_LE(p.NormalisedError(), max_nees) << p.id << ": error " << p.Error().transpose() * 1e3
                                               << " mm, sigma " << p.Sigma() * 1e3 << " mm";
    }
    if (p.role == "monitoring" || p.role == "radio") {
      if (moving) EXPECT_GE(p.alert_level, min_alert_moving) << p.id << " moves " << p.truth.norm() * 1e3 << " mm";
      if (!moving) EXPECT_LE(p.alert_level, max_alert_stable) << p.id << " is stable";
      if (p.forecast_valid && e.true_failure_time > 0.0) {
        EXPECT_LE(std::abs(p.forecast_time - e.true_failure_time), forecast_k * p.forecast_sigma)
            << p.id << ": forecast " << p.forecast_time << " +- " << p.forecast_sigma << ", truth "
            << e.true_failure_time;
      }
    }
    if (p.role == "control" || p.role == "check") EXPECT_LE(p.alert_level, max_alert_stable) << p.id;
    if (p.role == "radio") {
      ++radio;
      EXPECT_LE(p.Error().norm(), max_radio_error) << p.id << ": error " << p.Error().transpose() * 1e3 << " mm";
    }
  }
  EXPECT_GE(radio, min_radio_points) << "radio transmitters in the fused estimate";
  EXPECT_GE(monitoring, min_monitoring_points) << "monitoring targets in the fused estimate";
  if (monitoring > 0) EXPECT_LE(std::sqrt(sum2 / monitoring), max_rms);
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "full_graph_replay_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
