// deformation_estimator: fuses every source's point displacements into one
// deformation estimate of the slope (core/deformation/estimator.h), with
// alerts, failure-time forecasts, a SQLite history and reports.
// Thin wrapper: the work is ros_adapters::EstimatorStep (ros/estimator_step.h),
// which process_bag drives too; this nodelet subscribes, publishes (outputs
// converted by ros/deformation_conversions.h), writes reports on its timers
// and services, and diagnoses.
//
// The subscriptions are not lazy: the history must record every measurement
// whether or not anyone listens to the outputs.
#include <algorithm>
#include <memory>
#include <mutex>
#include <sstream>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/MarkerArray.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/ExportReport.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/SetReferenceEpoch.h"
#include "slope_monitor/SlopeDeformation.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/estimator_step.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class DeformationEstimatorNodelet : public nodelet::Nodelet {
 public:
  ~DeformationEstimatorNodelet() override {
    // End of a replay / shutdown: fuse what still waits for the other
    // inputs (they have ended), then write the reports once more.
    std::lock_guard<std::mutex> lock(mutex_);
    if (!step_) return;
    for (const ros_adapters::LogLine& line : step_->FinalReports()) {
      if (line.level == ros_adapters::LogLine::kError)
        ROS_ERROR("deformation_estimator: %s", line.text.c_str());
      else if (line.level == ros_adapters::LogLine::kWarn)
        ROS_WARN("deformation_estimator: %s", line.text.c_str());
      else
        ROS_INFO("deformation_estimator: %s", line.text.c_str());
    }
  }

 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          params_ = ros_adapters::ReadEstimatorParameters(p);
        })) {
      NODELET_ERROR("deformation_estimator: %s; not advertising", error->c_str());
      ReportSetUpFailure("parameters rejected: " + *error);
      return;
    }
    if (const auto error = ros_adapters::SetUpError([&] {
          // The inputs in one stamp order unless order_timeout is 0 (arrival order).
          step_ = std::make_unique<ros_adapters::EstimatorStep>(
              params_,
              params_.order_timeout > 0.0 ? params_.input_topics : std::vector<std::string>{},
              [](bool error, const std::string& m) {
                if (error) {
                  ROS_ERROR("deformation_estimator: %s", m.c_str());
                } else {
                  ROS_INFO("deformation_estimator: %s", m.c_str());
                }
              });
        })) {
      NODELET_ERROR(
          "deformation_estimator: %s; refusing to start on it (nothing was written to it); not "
          "advertising",
          error->c_str());
      ReportSetUpFailure("history database refused: " + *error);
      return;
    }
    if (params_.site)
      NODELET_INFO(
          "deformation_estimator: site '%s' (notification hook: %s)", params_.site->name.c_str(),
          params_.site->notification.hook.empty() ? "none"
                                                  : params_.site->notification.hook.c_str());
    const deformation::Snapshot resumed = step_->GetSnapshot();
    LogResumed(resumed);
    Advertise(pnh);
    Subscribe(pnh);
    StartTimers(nh, pnh);
    if (!resumed.points.empty()) {
      std::lock_guard<std::mutex> lock(mutex_);
      Publish(step_->Current(ros::Time(resumed.stamp)));
    }
  }

  void LogResumed(const deformation::Snapshot& resumed) {
    if (step_->has_history()) {
      NODELET_INFO(
          "deformation_estimator: history '%s': %zu point(s) resumed, reference epoch %u (stamp "
          "%.3f)",
          params_.database.c_str(), resumed.points.size(), resumed.reference_epoch,
          resumed.reference_stamp);
    } else {
      NODELET_WARN(
          "deformation_estimator: parameter 'database' is empty: no history is kept (a restart "
          "loses it)");
    }
  }

  void Advertise(ros::NodeHandle& pnh) {
    // Outputs and services under the node's own name (/deformation_estimator/deformation,
    // next to its parameters /deformation_estimator/<key>).
    deformation_pub_ = pnh.advertise<slope_monitor::SlopeDeformation>("deformation", 4, true);
    markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 2, true);
    points_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("points", 2, true);
    alerts_pub_ = pnh.advertise<diagnostic_msgs::DiagnosticArray>("alerts", 4, true);
    // A live installation may switch off the services that change state or
    // write files (ROS 1 has no authentication; doc/security.md).
    if (params_.enable_set_reference_epoch)
      reference_srv_ = pnh.advertiseService("set_reference_epoch",
                                            &DeformationEstimatorNodelet::OnSetReference, this);
    if (params_.enable_export_report)
      export_srv_ =
          pnh.advertiseService("export_report", &DeformationEstimatorNodelet::OnExport, this);
  }

  // Relative input topics are the node's own (/deformation_estimator/displacements),
  // like its outputs; the graphs give absolute ones.
  void Subscribe(ros::NodeHandle& nh) {
    for (const std::string& topic : params_.input_topics) {
      const boost::function<void(const slope_monitor::PointDisplacementArray::ConstPtr&)> callback =
          [this, topic](const slope_monitor::PointDisplacementArray::ConstPtr& msg) {
            std::lock_guard<std::mutex> lock(mutex_);
            Publish(step_->AddDisplacements(*msg, topic, ros::WallTime::now().toSec()));
          };
      subscribers_.push_back(
          nh.subscribe<slope_monitor::PointDisplacementArray>(topic, 64, callback));
    }
    for (const std::string& topic : params_.area_topics) {
      const boost::function<void(const slope_monitor::ChangeAreaArray::ConstPtr&)> callback =
          [this, topic](const slope_monitor::ChangeAreaArray::ConstPtr& msg) {
            std::lock_guard<std::mutex> lock(mutex_);
            Publish(step_->AddAreas(*msg, topic));
          };
      subscribers_.push_back(nh.subscribe<slope_monitor::ChangeAreaArray>(topic, 8, callback));
    }
  }

  // Diagnostics, the input order's live time-out (and the end of a replay),
  // reports on a timer.
  void StartTimers(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("deformation_estimator");
    updater_->add("deformation_estimator", this, &DeformationEstimatorNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    if (params_.order_timeout > 0.0) {
      order_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                        [this](const ros::WallTimerEvent&) { OnOrderTimer(); });
      // The end of a replay (ros/setup.h): what waits for a later stamp of
      // another input is fused (and published).
      end_sub_ = ros_adapters::SubscribeEndOfInput(nh, ros_adapters::kEndOfFusion, [this] {
        std::lock_guard<std::mutex> lock(mutex_);
        Publish(step_->Flush());
      });
    }
    if (params_.report_interval > 0.0 && !params_.report_dir.empty()) {
      report_timer_ = nh.createWallTimer(ros::WallDuration(params_.report_interval),
                                         [this](const ros::WallTimerEvent&) {
                                           std::lock_guard<std::mutex> lock(mutex_);
                                           WriteReportsNow("on the report timer");
                                         });
    }
  }

  // A node that cannot do its job says so: ERROR on /diagnostics every
  // second until it is restarted with the cause fixed (ros/setup.h).
  void ReportSetUpFailure(const std::string& cause) {
    step_.reset();
    setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
        getNodeHandle(), getPrivateNodeHandle(), "deformation_estimator", cause,
        std::vector<std::pair<std::string, std::string>>{
            {"database", params_.database.empty() ? "(none)" : params_.database}});
  }

  // Caller holds mutex_.
  void WriteReportsNow(const char* why) {
    if (!step_ || params_.report_dir.empty() || step_->GetSnapshot().points.empty()) return;
    try {
      const auto files = step_->WriteReports("", params_.report_formats);
      NODELET_INFO("deformation_estimator: wrote %zu report file(s) to %s %s", files.size(),
                   params_.report_dir.c_str(), why);
    } catch (const std::exception& e) {
      step_->set_last_problem(e.what());
      NODELET_ERROR("deformation_estimator: reports %s failed: %s", why, e.what());
    }
  }

  // Live: a batch that waited order_timeout for a silent input is fused without it.
  void OnOrderTimer() {
    if (!ros_adapters::LiveTimeouts()) return;  // replay: the destructor flushes
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::string> given_up;
    Publish(step_->Expire(ros::WallTime::now().toSec(), params_.order_timeout, &given_up));
    std::string names;
    for (const std::string& t : given_up) names += (names.empty() ? "'" : ", '") + t + "'";
    // Said when the inputs given up on change (a live camera graph gives up
    // on the adjuster between its epochs, hours apart: once, not every time).
    if (!names.empty() && names != given_up_names_)
      NODELET_WARN(
          "deformation_estimator: gave up waiting for %s (nothing newer for order_timeout %.0f s); "
          "fused the other inputs' batches without it",
          names.c_str(), params_.order_timeout);
    if (!names.empty()) given_up_names_ = names;
  }

  // Caller holds mutex_. Problems throttled; alert changes never.
  void Publish(const ros_adapters::EstimatorResult& result) {
    for (const ros_adapters::LogLine& line : result.problems) {
      if (line.level == ros_adapters::LogLine::kError)
        NODELET_ERROR_THROTTLE(5.0, "deformation_estimator: %s", line.text.c_str());
      else if (line.level == ros_adapters::LogLine::kInfo)
        NODELET_INFO("deformation_estimator: %s", line.text.c_str());
      else
        NODELET_WARN_THROTTLE(10.0, "deformation_estimator: %s", line.text.c_str());
    }
    for (const ros_adapters::EstimatorPublication& p : result.publications) Publish(p);
  }

  void Publish(const ros_adapters::EstimatorPublication& p) {
    for (const ros_adapters::LogLine& line : p.log) {
      if (line.level == ros_adapters::LogLine::kError) {
        NODELET_ERROR("deformation_estimator: %s", line.text.c_str());
      } else if (line.level == ros_adapters::LogLine::kWarn) {
        NODELET_WARN("deformation_estimator: %s", line.text.c_str());
      } else {
        NODELET_INFO("deformation_estimator: %s", line.text.c_str());
      }
    }
    if (params_.report_on_alert_change && !p.changes.empty())
      WriteReportsNow("on an alert-level change");
    deformation_pub_.publish(ros_adapters::ToMsg(p.snapshot, p.header));
    if (markers_pub_.getNumSubscribers() > 0)
      markers_pub_.publish(ros_adapters::ToMarkers(p.snapshot, p.header, params_.markers));
    if (points_pub_.getNumSubscribers() > 0)
      points_pub_.publish(ros_adapters::ToCloud(p.snapshot, p.header));
    alerts_pub_.publish(ros_adapters::ToAlerts(p.snapshot, p.header));
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req,
                      slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      const ros_adapters::EstimatorPublication p =
          step_->SetReferenceEpoch(req.epoch, req.use_latest, &res.reference_epoch);
      res.success = true;
      res.message = Message("reference epoch is now ", res.reference_epoch);
      Publish(p);
    } catch (const Error& e) {
      res.success = false;
      res.message = e.what();
    }
    return true;
  }

  bool OnExport(slope_monitor::ExportReport::Request& req,
                slope_monitor::ExportReport::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      // output_dir names a subfolder of report_dir, never a path of its own.
      res.files = step_->ExportReports(req.output_dir, req.formats);
      res.success = true;
      res.message = Message("wrote ", res.files.size(), " file(s) to ", params_.report_dir, "/",
                            req.output_dir);
    } catch (const std::exception& e) {
      res.success = false;
      res.files.clear();  // never present a partial set as complete
      res.message = e.what();
    }
    return true;
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    step_->Diagnose(stat);
  }

  std::mutex mutex_;
  ros_adapters::EstimatorParameters params_;
  std::unique_ptr<ros_adapters::EstimatorStep> step_;  // null: set-up failed
  ros::WallTimer report_timer_;
  ros::Subscriber end_sub_;  // replay only: the end of the input
  ros::WallTimer order_timer_;
  std::string given_up_names_;  // the inputs the order last gave up on
  std::vector<ros::Subscriber> subscribers_;
  ros::Publisher deformation_pub_, markers_pub_, points_pub_, alerts_pub_;
  ros::ServiceServer reference_srv_, export_srv_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DeformationEstimatorNodelet, nodelet::Nodelet)
