// bundle_adjuster nodelet: converts the target observations, tie points,
// camera infos, GNSS position priors and epoch markers of the graph into the
// core's EpochCollector (which decides when an epoch is complete, see
// core/adjustment/epoch_collector.h), and publishes what the core computes for
// each complete epoch: the solution, tf of every camera, the adjusted points
// with their sigma, the camera frustums (rviz), and displacements of monitoring points against the
// reference epoch. The process_bag tool drives the same core the same way.
#include <algorithm>
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
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/ros/resect_service.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {

class BundleAdjusterNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      NODELET_ERROR("bundle_adjuster: %s; not advertising anything", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "bundle_adjuster", "parameters rejected: " + *error);
      return;
    }
    // Outputs and services under the node's own name (launched at the root as
    // /bundle_adjuster: parameters /bundle_adjuster/<key>, outputs
    // /bundle_adjuster/solution, ...); inputs relative to its namespace.
    solution_pub_ = pnh.advertise<slope_monitor::AdjustmentSolution>("solution", 5, true);
    points_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("points", 5, true);
    displacements_pub_ =
        pnh.advertise<slope_monitor::PointDisplacementArray>("displacements", 5, true);
    frustums_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("frustums", 1, true);
    for (const std::string& topic : params_.target_topics)
      target_subs_.push_back(nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnTargets, this));
    for (const std::string& cam : params_.collector.cameras) {
      info_subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          params_.CameraInfoTopic(cam), 5,
          [this, cam](const sensor_msgs::CameraInfoConstPtr& m) { OnCameraInfo(cam, m); }));
    }
    // Large queues: a long solve holds the callbacks, and nothing may be lost.
    for (const std::string& topic : params_.tie_topics)
      tie_subs_.push_back(nh.subscribe(topic, 2000, &BundleAdjusterNodelet::OnTiePoints, this));
    for (const std::string& topic : params_.prior_topics)
      prior_subs_.push_back(nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnPositionPrior, this));
    for (const std::string& topic : params_.epoch_topics)
      epoch_subs_.push_back(nh.subscribe(topic, 20, &BundleAdjusterNodelet::OnEpoch, this));
    // The configured cameras' markers in epoch order: each camera's topic is
    // in order, but on a fast replay or a busy machine one camera's next
    // epoch can overtake another's end marker, which would cut that one short.
    if (!params_.collector.cameras.empty())
      marker_order_ = std::make_unique<InputOrder<slope_monitor::EpochMarkerConstPtr>>(
          params_.collector.cameras);
    // A live installation may switch off the services that change state (ROS 1
    // has no authentication; doc/security.md).
    if (params_.enable_run_adjustment)
      run_srv_ = pnh.advertiseService("run_adjustment", &BundleAdjusterNodelet::OnRun, this);
    if (params_.enable_set_reference_epoch)
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
    updater_->add("adjustment", this, &BundleAdjusterNodelet::Diagnose);
    NODELET_INFO("bundle_adjuster: %zu target topics, %zu cameras, %zu targets in '%s'",
                 params_.target_topics.size(), params_.collector.cameras.size(),
                 params_.targets.targets().size(), params_.target_list_path.c_str());
  }

 private:
  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    params_ = ros_adapters::ReadAdjusterParameters(p);
    collector_ = std::make_unique<adjustment::EpochCollector>(params_.collector, &params_.targets);
  }

  // ---------------------------------------------------------------- input
  static double Now() { return ros::WallTime::now().toSec(); }

  void OnCameraInfo(const std::string& camera_name, const sensor_msgs::CameraInfoConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      models_[camera_name] =
          ros_adapters::CameraModelFromCameraInfo(*msg, params_.PixelSizeOf(camera_name));
    } catch (const Error& e) {
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: camera_info of '%s': %s", camera_name.c_str(),
                             e.what());
    }
  }

  // A replay of a site file's graph waits only for the cameras the bag has:
  // without time-outs, a listed camera that never sends (the UAV did not fly)
  // would hold every epoch to the end. Decided once, at the first input,
  // by which epoch topics have a publisher (the player advertises all of its
  // bag's topics before it plays), as process_bag takes the bag's cameras.
  // Caller holds mutex_.
  void CheckReplayCameras() {
    if (cameras_checked_) return;
    cameras_checked_ = true;
    if (ros_adapters::LiveTimeouts() || !params_.cameras_from_site ||
        epoch_subs_.size() != params_.collector.cameras.size())
      return;
    std::vector<std::string> kept;
    for (size_t i = 0; i < epoch_subs_.size(); ++i) {
      if (epoch_subs_[i].getNumPublishers() > 0) {
        kept.push_back(params_.collector.cameras[i]);
      } else {
        NODELET_INFO("bundle_adjuster: camera '%s' of the site file has nothing on %s in this replay: "
                     "epochs do not wait for it",
                     params_.collector.cameras[i].c_str(), epoch_subs_[i].getTopic().c_str());
      }
    }
    if (kept.size() == params_.collector.cameras.size() || kept.empty()) return;
    params_.collector.cameras = kept;
    collector_ = std::make_unique<adjustment::EpochCollector>(params_.collector, &params_.targets);
    marker_order_ = std::make_unique<InputOrder<slope_monitor::EpochMarkerConstPtr>>(kept);
  }

  // Whether a matcher publishes tie points (none started, or it failed on
  // its parameters: nothing to wait for).
  bool MatcherPublishing() const {
    for (const ros::Subscriber& s : tie_subs_)
      if (s.getNumPublishers() > 0) return true;
    return false;
  }

  void OnTargets(const slope_monitor::TargetObservationArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    collector_->SetTiePointsExpected(MatcherPublishing());
    Solve(collector_->AddTargets(ros_adapters::FromMsg(*msg), Now()));
  }

  void OnTiePoints(const slope_monitor::TiePointArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    // No matcher publishing (not started, or failed on its parameters):
    // nothing to wait for.
    collector_->SetTiePointsExpected(MatcherPublishing());
    Solve(collector_->AddTies(ros_adapters::FromMsg(*msg), Now()));
  }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    collector_->AddPrior(ros_adapters::FromMsg(*msg));
  }

  // Begin and end markers: both move their camera on in the marker order.
  void OnEpoch(const slope_monitor::EpochMarkerConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    CheckReplayCameras();
    const auto& cameras = params_.collector.cameras;
    // A camera's marker of epoch k waits until every camera has begun epoch k
    // (unnumbered markers, epoch 0, are not held).
    if (!marker_order_ || msg->epoch == 0 ||
        std::find(cameras.begin(), cameras.end(), msg->source) == cameras.end()) {
      RouteEnd(msg);
      return;
    }
    for (auto& r : marker_order_->Add(msg->source, msg->epoch, msg, Now())) RouteEnd(r.item);
  }

  // Caller holds mutex_.
  void RouteEnd(const slope_monitor::EpochMarkerConstPtr& msg) {
    if (!msg->end) return;
    collector_->SetTiePointsExpected(MatcherPublishing());
    Solve(collector_->AddEnd(ros_adapters::FromMsg(*msg), Now()));
    for (; reported_ignored_ < collector_->ignored().size(); ++reported_ignored_)
      NODELET_WARN("bundle_adjuster: %s", collector_->ignored()[reported_ignored_].c_str());
  }

  void OnTimer(const ros::WallTimerEvent&) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (marker_order_ && ros_adapters::LiveTimeouts()) {
        // Live: a camera silent for epoch_wait no longer holds the others' markers.
        std::vector<std::string> given_up;
        for (auto& r : marker_order_->Expire(Now(), params_.collector.epoch_wait, &given_up))
          RouteEnd(r.item);
        for (const std::string& c : given_up)
          NODELET_WARN(
              "bundle_adjuster: no epoch marker of '%s' for epoch_wait %.0f s: the other cameras' "
              "markers "
              "go on without it",
              c.c_str(), params_.collector.epoch_wait);
      }
      if (ros_adapters::LiveTimeouts()) {
        collector_->SetTiePointsExpected(MatcherPublishing());
        Solve(collector_->Poll(Now()));
      }
    }
    if (updater_) updater_->update();
  }

  // The end of a replay (ros/setup.h): markers held for a camera that never
  // sent its next one go on, and the epoch still open is solved with what it
  // has (process_bag's Finish); the log names what was missing.
  void OnEndOfInput() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (marker_order_)
      for (auto& r : marker_order_->Flush()) RouteEnd(r.item);
    collector_->SetTiePointsExpected(MatcherPublishing());
    if (const std::optional<adjustment::CollectedEpoch> e = collector_->Finish()) {
      NODELET_INFO("bundle_adjuster: end of the replay: solving the epoch still open");
      SolveOne(*e);
    }
  }

  bool OnRun(slope_monitor::RunAdjustment::Request& req,
             slope_monitor::RunAdjustment::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (req.epoch != 0 && req.epoch != collector_->current_epoch()) {
      res.success = false;
      res.message = "only the epoch being collected (" +
                    std::to_string(collector_->current_epoch()) + ") can be solved";
      return true;
    }
    res.solution = SolveOne(collector_->TakeNow());
    res.success = res.solution.usable;
    res.message = res.solution.message;
    return true;
  }

  bool OnResect(slope_monitor::ResectCamera::Request& req, slope_monitor::ResectCamera::Response& res) {
    ros_adapters::Resect(req, &res);
    if (!res.success) NODELET_WARN("bundle_adjuster: resect_camera: %s", res.message.c_str());
    return true;
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req,
                      slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    int chosen = -1;
    const std::string error =
        store_.SetReference(req.use_latest, static_cast<int>(req.epoch), &chosen);
    res.success = error.empty();
    res.message = error.empty() ? "reference epoch set to " + std::to_string(chosen) : error;
    if (res.success) res.reference_epoch = chosen;
    return true;
  }

  // ---------------------------------------------------------------- solve
  void Solve(const std::vector<adjustment::CollectedEpoch>& epochs) {
    for (const adjustment::CollectedEpoch& e : epochs) SolveOne(e);
  }

  slope_monitor::AdjustmentSolution SolveOne(const adjustment::CollectedEpoch& epoch) {
    const ros_adapters::SolvedEpoch out =
        ros_adapters::SolveCollectedEpoch(epoch, models_, params_, getName(), &store_);
    for (const ros_adapters::LogLine& line : out.log) {
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
    if (out.adjusted) {
      last_photos_ = out.photos;
      last_naming_ = out.naming;
      last_rejected_names_ = out.rejected_names;
    }
    last_message_ = out.solution.message;
    last_usable_ = out.accepted;
    solution_pub_.publish(out.solution);
    if (!out.accepted) return out.solution;
    // Fixed cameras on /tf_static (latched), each UAV photo as its own stamped transform on /tf.
    if (!out.fixed_transforms.empty()) static_broadcaster_.sendTransform(out.fixed_transforms);
    if (!out.moving_transforms.empty()) tf_broadcaster_.sendTransform(out.moving_transforms);
    points_pub_.publish(out.points);
    if (out.displacements) displacements_pub_.publish(*out.displacements);
    frustums_pub_.publish(ros_adapters::ToFrustumMarkers(out.solution, models_, params_.frustums));
    ++accepted_;
    return out.solution;
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_message_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "waiting for an epoch");
    } else if (last_usable_) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, last_message_);
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "last epoch not usable: " + last_message_);
    }
    stat.add("collected observations", collector_->num_observations());
    stat.add("collected images", collector_->num_images());
    stat.add("accepted epochs", accepted_);
    stat.add("unidentified observations received", collector_->unidentified_received());
    stat.add("observations dropped: bad pixel or covariance", collector_->observations_dropped());
    stat.add("UAV photos last epoch", last_photos_.total);
    stat.add("UAV photos kept", last_photos_.kept);
    stat.add("UAV photos dropped: not oriented", last_photos_.not_oriented);
    stat.add("UAV photos dropped: too few observations", last_photos_.too_few_observations);
    stat.add("targets named by projection", last_naming_.named);
    stat.add("targets left unnamed: ambiguous", last_naming_.ambiguous);
    stat.add("targets left unnamed: no listed target near", last_naming_.unmatched);
    stat.add("targets left unnamed: image not oriented", last_naming_.not_oriented);
    stat.add("names rejected by the residual test", last_rejected_names_);
    stat.add("tie-point observation pairs used", collector_->tie_points_used());
    stat.add("tie points skipped: low quality", collector_->tie_points_low_quality());
    stat.add("reference epoch", store_.reference_epoch());
  }

  ros_adapters::AdjusterParameters params_;

  // State (guarded by mutex_; a solve holds it, as the callbacks wait anyway).
  std::mutex mutex_;
  std::unique_ptr<adjustment::EpochCollector> collector_;
  adjustment::EpochStore store_;
  std::map<std::string, camera::CameraModel> models_;
  size_t reported_ignored_ = 0;
  adjustment::PhotoStats last_photos_;
  adjustment::NamingReport last_naming_;
  int last_rejected_names_ = 0;
  std::string last_message_;
  bool last_usable_ = false;
  int accepted_ = 0;

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
  std::unique_ptr<InputOrder<slope_monitor::EpochMarkerConstPtr>>
      marker_order_;  // null without cameras
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::BundleAdjusterNodelet, nodelet::Nodelet)
