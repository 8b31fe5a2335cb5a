// bundle_adjuster nodelet: converts the target observations, tie points,
// camera infos, GNSS position priors and epoch markers of the graph into the
// core's EpochCollector (which decides when an epoch is complete, see
// core/adjustment/epoch_collector.h), and publishes what the core computes for
// each complete epoch: the solution, tf of every camera, the adjusted points
// with their sigma, the camera frustums (rviz), and displacements of monitoring points against the
// reference epoch. The work is ros_adapters::AdjusterStep (ros/adjuster_step.h),
// which process_bag drives too; this nodelet subscribes, orders the cameras'
// markers (ros_adapters::EpochMarkerOrder), publishes and diagnoses.
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RunAdjustment.h"
#include "slope_monitor/SetReferenceEpoch.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/adjuster_step.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/resect_service.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class BundleAdjusterNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          step_ = std::make_unique<ros_adapters::AdjusterStep>(
              ros_adapters::ReadAdjusterParameters(p), getName());
        })) {
      NODELET_ERROR("bundle_adjuster: %s; not advertising anything", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "bundle_adjuster", "parameters rejected: " + *error);
      return;
    }
    if (!step_->resumed().empty()) NODELET_INFO("bundle_adjuster: %s", step_->resumed().c_str());
    // Outputs and services under the node's own name (launched at the root as
    // /bundle_adjuster: parameters /bundle_adjuster/<key>, outputs
    // /bundle_adjuster/solution, ...); inputs relative to its namespace.
    solution_pub_ = pnh.advertise<slope_monitor::AdjustmentSolution>("solution", 5, true);
    points_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("points", 5, true);
    displacements_pub_ =
        pnh.advertise<slope_monitor::PointDisplacementArray>("displacements", 5, true);
    frustums_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("frustums", 1, true);
    // The configured cameras' markers in epoch order (ros/adjuster_step.h).
    marker_order_ = std::make_unique<ros_adapters::EpochMarkerOrder>(params().collector.cameras);
    for (const std::string& topic : params().target_topics)
      target_subs_.push_back(nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnTargets, this));
    for (const std::string& cam : params().collector.cameras) {
      info_subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          params().CameraInfoTopic(cam), 5,
          [this, cam](const sensor_msgs::CameraInfoConstPtr& m) { OnCameraInfo(cam, m); }));
    }
    // Large queues: a long solve holds the callbacks, and nothing may be lost.
    for (const std::string& topic : params().tie_topics)
      tie_subs_.push_back(nh.subscribe(topic, 2000, &BundleAdjusterNodelet::OnTiePoints, this));
    for (const std::string& topic : params().prior_topics)
      prior_subs_.push_back(
          nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnPositionPrior, this));
    for (const std::string& topic : params().epoch_topics)
      epoch_subs_.push_back(nh.subscribe(topic, 20, &BundleAdjusterNodelet::OnEpoch, this));
    // A live installation may switch off the services that change state (ROS 1
    // has no authentication; doc/security.md).
    if (params().enable_run_adjustment)
      run_srv_ = pnh.advertiseService("run_adjustment", &BundleAdjusterNodelet::OnRun, this);
    if (params().enable_set_reference_epoch)
      reference_srv_ =
          pnh.advertiseService("set_reference_epoch", &BundleAdjusterNodelet::OnSetReference, this);
    // Resection of a camera from surveyed points (ros/resect_service.h): it
    // computes and answers, and changes no state of the adjuster.
    resect_srv_ = pnh.advertiseService("resect_camera", &BundleAdjusterNodelet::OnResect, this);
    // The collector's time-outs are for live sensors only (a complete epoch is
    // decided by the messages; none in a replay, ros/setup.h LiveTimeouts).
    gap_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &BundleAdjusterNodelet::OnTimer, this);
    end_sub_ = ros_adapters::SubscribeEndOfInput(nh, ros_adapters::kEndOfAdjustment,
                                                 [this] { OnEndOfInput(); });
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("bundle_adjuster");
    updater_->add("adjustment", [this](diagnostic_updater::DiagnosticStatusWrapper& stat) {
      std::lock_guard<std::mutex> lock(mutex_);
      step_->Diagnose(stat);
    });
    NODELET_INFO("bundle_adjuster: %zu target topics, %zu cameras, %zu targets in '%s'",
                 params().target_topics.size(), params().collector.cameras.size(),
                 params().targets.targets().size(), params().target_list_path.c_str());
  }

 private:
  const ros_adapters::AdjusterParameters& params() const { return step_->parameters(); }

  static double Now() { return ros::WallTime::now().toSec(); }

  // A replay of a site file's graph waits only for the cameras the bag has
  // (ros_adapters::ReplayCameras, as process_bag decides it): decided once, at
  // the first input, by which epoch topics have a publisher (the player
  // advertises all of its bag's topics before it plays). Caller holds mutex_.
  void CheckReplayCameras() {
    if (cameras_checked_) return;
    cameras_checked_ = true;
    if (ros_adapters::LiveTimeouts()) return;
    std::map<std::string, const ros::Subscriber*> epoch_sub;
    for (size_t i = 0; i < epoch_subs_.size() && i < params().collector.cameras.size(); ++i)
      epoch_sub[params().collector.cameras[i]] = &epoch_subs_[i];
    std::vector<ros_adapters::LogLine> log;
    const std::vector<std::string> kept = ros_adapters::ReplayCameras(
        params(),
        [&](const std::string& camera) {
          const auto it = epoch_sub.find(camera);
          return it == epoch_sub.end() || it->second->getNumPublishers() > 0;
        },
        &log);
    Log(log);
    if (kept == params().collector.cameras) return;
    step_->KeepCameras(kept);
    marker_order_ = std::make_unique<ros_adapters::EpochMarkerOrder>(kept);
  }

  // Whether a matcher publishes tie points (none started, or it failed on
  // its parameters: nothing to wait for).
  bool MatcherPublishing() const {
    for (const ros::Subscriber& s : tie_subs_)
      if (s.getNumPublishers() > 0) return true;
    return false;
  }

  void OnCameraInfo(const std::string& camera_name, const sensor_msgs::CameraInfoConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (const auto error = step_->OnCameraInfo(camera_name, *msg))
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: camera_info of '%s': %s", camera_name.c_str(),
                             error->c_str());
  }

  void OnTargets(const slope_monitor::TargetObservationArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    step_->SetTiePointsExpected(MatcherPublishing());
    Publish(step_->AddTargets(*msg, Now()));
  }

  void OnTiePoints(const slope_monitor::TiePointArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    step_->SetTiePointsExpected(MatcherPublishing());
    Publish(step_->AddTies(*msg, Now()));
  }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    step_->AddPrior(*msg);
  }

  // Begin and end markers: both move their camera on in the marker order.
  void OnEpoch(const slope_monitor::EpochMarkerConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    for (const auto& marker : marker_order_->Add(msg, Now())) RouteEnd(marker);
  }

  // Caller holds mutex_.
  void RouteEnd(const slope_monitor::EpochMarkerConstPtr& msg) {
    if (!msg->end) return;
    step_->SetTiePointsExpected(MatcherPublishing());
    std::vector<ros_adapters::LogLine> ignored;
    const std::vector<ros_adapters::SolvedEpoch> epochs = step_->AddEnd(*msg, Now(), &ignored);
    Log(ignored);
    Publish(epochs);
  }

  void OnTimer(const ros::WallTimerEvent&) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const double wait = params().collector.epoch_wait;
      if (ros_adapters::LiveTimeouts()) {
        // Live: a camera silent for epoch_wait no longer holds the others' markers.
        std::vector<std::string> given_up;
        for (const auto& marker : marker_order_->Expire(Now(), wait, &given_up)) RouteEnd(marker);
        for (const std::string& c : given_up)
          NODELET_WARN(
              "bundle_adjuster: no epoch marker of '%s' for epoch_wait %.0f s: the other "
              "cameras' markers go on without it",
              c.c_str(), wait);
      }
      if (ros_adapters::LiveTimeouts()) {
        step_->SetTiePointsExpected(MatcherPublishing());
        Publish(step_->Poll(Now()));
      }
    }
    if (updater_) updater_->update();
  }

  // The end of a replay (ros/setup.h): markers held for a camera that never
  // sent its next one go on, and the epoch still open is solved with what it
  // has (process_bag's Finish); the log names what was missing.
  void OnEndOfInput() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& marker : marker_order_->Flush()) RouteEnd(marker);
    step_->SetTiePointsExpected(MatcherPublishing());
    if (const std::optional<ros_adapters::SolvedEpoch> e = step_->Finish()) {
      NODELET_INFO("bundle_adjuster: end of the replay: solving the epoch still open");
      Publish(*e);
    }
  }

  bool OnRun(slope_monitor::RunAdjustment::Request& req,
             slope_monitor::RunAdjustment::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (req.epoch != 0 && req.epoch != step_->current_epoch()) {
      res.success = false;
      res.message = "only the epoch being collected (" + std::to_string(step_->current_epoch()) +
                    ") can be solved";
      return true;
    }
    const ros_adapters::SolvedEpoch out = step_->SolveNow();
    Publish(out);
    res.solution = out.solution;
    res.success = res.solution.usable;
    res.message = res.solution.message;
    return true;
  }

  bool OnResect(slope_monitor::ResectCamera::Request& req,
                slope_monitor::ResectCamera::Response& res) {
    ros_adapters::Resect(req, &res);
    if (!res.success) NODELET_WARN("bundle_adjuster: resect_camera: %s", res.message.c_str());
    return true;
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req,
                      slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    int chosen = -1;
    const std::string error =
        step_->store().SetReference(req.use_latest, static_cast<int>(req.epoch), &chosen);
    res.success = error.empty();
    res.message = error.empty() ? "reference epoch set to " + std::to_string(chosen) : error;
    if (res.success) {
      res.reference_epoch = chosen;
      step_->SaveStore();  // the site's history keeps the reference
    }
    return true;
  }

  // ---------------------------------------------------------------- publish
  void Log(const std::vector<ros_adapters::LogLine>& lines) const {
    for (const ros_adapters::LogLine& line : lines) {
      switch (line.level) {
        case ros_adapters::LogLine::kDebug:
          NODELET_DEBUG("bundle_adjuster: %s", line.text.c_str());
          break;
        case ros_adapters::LogLine::kInfo:
          NODELET_INFO("bundle_adjuster: %s", line.text.c_str());
          break;
        case ros_adapters::LogLine::kWarn:
          NODELET_WARN("bundle_adjuster: %s", line.text.c_str());
          break;
        case ros_adapters::LogLine::kError:
          NODELET_ERROR("bundle_adjuster: %s", line.text.c_str());
          break;
      }
    }
  }

  void Publish(const std::vector<ros_adapters::SolvedEpoch>& epochs) {
    for (const ros_adapters::SolvedEpoch& e : epochs) Publish(e);
  }

  void Publish(const ros_adapters::SolvedEpoch& out) {
    Log(out.log);
    solution_pub_.publish(out.solution);
    if (!out.accepted) return;
    // Fixed cameras on /tf_static (latched), each UAV photo as its own stamped transform on /tf.
    if (!out.fixed_transforms.empty()) static_broadcaster_.sendTransform(out.fixed_transforms);
    if (!out.moving_transforms.empty()) tf_broadcaster_.sendTransform(out.moving_transforms);
    points_pub_.publish(out.points);
    if (out.displacements) displacements_pub_.publish(*out.displacements);
    frustums_pub_.publish(step_->Frustums(out));
  }

  // State (guarded by mutex_; a solve holds it, as the callbacks wait anyway).
  std::mutex mutex_;
  std::unique_ptr<ros_adapters::AdjusterStep> step_;

  // ROS.
  ros::Publisher solution_pub_, points_pub_, displacements_pub_, frustums_pub_;
  std::vector<ros::Subscriber> target_subs_, info_subs_;
  std::vector<ros::Subscriber> tie_subs_;
  std::vector<ros::Subscriber> prior_subs_;
  bool cameras_checked_ = false;  // CheckReplayCameras ran
  std::vector<ros::Subscriber> epoch_subs_;
  ros::ServiceServer run_srv_, reference_srv_, resect_srv_;
  ros::WallTimer gap_timer_;
  ros::Subscriber end_sub_;  // replay only: the end of the input
  std::unique_ptr<ros_adapters::EpochMarkerOrder> marker_order_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::BundleAdjusterNodelet, nodelet::Nodelet)
