// Plays a simulated survey bag through the whole graph (replay.launch, with
// --clock) and checks the deformation estimator's stored history against the
// simulator's truth. Expected values and tolerances come in as parameters
// (test/rostest/full_graph_replay.test). It also listens to every fixed
// camera's target observations and checks them against the truth: every
// visible target observed in every image, each observed ID where the truth
// projects that target, no false IDs.
#include <map>
#include <mutex>
#include <set>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <ros/ros.h>

#include <gtest/gtest.h>

#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"
#include "slope_monitor/core/sim/truth.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

using rostest_node::Param;

// Target observations of one image, as published by a centroider.
struct SeenImage {
  std::string camera;
  double stamp = 0.0;
  std::map<std::string, Eigen::Vector2d> identified;  // key -> pixel
  int unknown = 0;
};

class TargetRecorder {
 public:
  explicit TargetRecorder(ros::NodeHandle& nh, const std::vector<std::string>& cameras) {
    for (const std::string& c : cameras)
      subs_.push_back(nh.subscribe("/" + c + "/targets", 100, &TargetRecorder::On, this));
  }
  std::vector<SeenImage> Images() {
    std::lock_guard<std::mutex> lock(mutex_);
    return images_;
  }

 private:
  void On(const slope_monitor::TargetObservationArrayConstPtr& msg) {
    SeenImage im;
    im.camera = msg->camera_name;
    im.stamp = msg->header.stamp.toSec();
    for (const auto& o : msg->observations) {
      if (o.id < 0)
        ++im.unknown;
      else
        im.identified[o.family + "/" + std::to_string(o.id)] = Eigen::Vector2d(o.x, o.y);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    images_.push_back(im);
  }
  std::vector<ros::Subscriber> subs_;
  std::mutex mutex_;
  std::vector<SeenImage> images_;
};

std::unique_ptr<TargetRecorder> recorder;

// Every fixed-camera image of the bag: its targets observed, IDs where the
// truth projects them (within max_id_px), nothing identified that is not there.
void CheckTargetObservations(const sim::SurveyTruth& truth, const std::vector<SeenImage>& seen, double max_id_px) {
  int images = 0, checked_ids = 0;
  for (const sim::CameraTruth& cam : truth.cameras) {
    if (cam.kind != "fixed") continue;
    for (const sim::ImageTruth& im : cam.images) {
      ++images;
      const SeenImage* s = nullptr;
      for (const SeenImage& x : seen)
        if (x.camera == cam.name && std::abs(x.stamp - im.stamp) < 1e-3) s = &x;
      ASSERT_NE(s, nullptr) << cam.name << " image at " << im.stamp << ": no target observations published";
      for (const std::string& key : im.visible)
        EXPECT_TRUE(s->identified.count(key)) << cam.name << "@" << im.stamp << ": visible target " << key
                                              << " not observed";
      for (const auto& [key, px] : s->identified) {
        const sim::TargetTruth* t = truth.FindTarget(key);
        ASSERT_NE(t, nullptr) << cam.name << "@" << im.stamp << ": false ID " << key << " (no such target)";
        Eigen::Vector2d expect;
        ASSERT_TRUE(cam.model.Project(im.exterior, t->positions.at(im.epoch), &expect)) << key;
        EXPECT_LT((px - expect).norm(), max_id_px)
            << cam.name << "@" << im.stamp << ": " << key << " observed at " << px.transpose() << ", truth projects it to "
            << expect.transpose();
        ++checked_ids;
      }
      EXPECT_EQ(s->unknown, 0) << cam.name << "@" << im.stamp << ": unidentified targets";
    }
  }
  std::cout << "target observations: " << images << " fixed-camera images, " << checked_ids
            << " identified observations checked against the truth\n";
  EXPECT_GT(images, 0);
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
  ASSERT_TRUE(rostest_node::WaitForClock(bag_end - ros::Duration(end_margin), timeout))
      << "the bag did not finish playing; clock at " << ros::Time::now() << ", end " << bag_end;
  ros::WallDuration(settle).sleep();

  const sim::SurveyTruth truth = sim::SurveyTruth::Load(truth_path);
  CheckTargetObservations(truth, recorder->Images(), Param(pnh, "max_id_px", 1.0));
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
  ros::NodeHandle nh;
  slope_monitor::recorder = std::make_unique<slope_monitor::TargetRecorder>(
      nh, std::vector<std::string>{"fixed_cam_1", "fixed_cam_2"});
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  slope_monitor::recorder.reset();
  return result;
}
