// deformation_estimator: fuses every source's point displacements into one
// deformation estimate of the slope (core/deformation/estimator.h), with
// alerts, failure-time forecasts, a SQLite history and reports.
// Thin wrapper: parameters -> EstimatorOptions, messages -> Batch, the core
// does the rest; outputs are converted by ros/deformation_conversions.h.
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
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/deformation/alert_hook.h"
#include "slope_monitor/core/deformation/alert_log.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/deformation/plot_report.h"
#include "slope_monitor/core/deformation/report.h"
#include "slope_monitor/core/io/safe_file.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/change_area_conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {

class DeformationEstimatorNodelet : public nodelet::Nodelet {
 public:
  ~DeformationEstimatorNodelet() override {
    // End of a replay / shutdown: fuse what still waits for the other
    // inputs (they have ended), then write the reports once more.
    std::lock_guard<std::mutex> lock(mutex_);
    if (estimator_ && order_) {
      for (auto& r : order_->Flush()) Fuse(r.item, r.input, false);
    }
    if (estimator_ && report_on_shutdown_ && !report_dir_.empty() &&
        estimator_->GetSnapshot().points.empty()) {
      // An empty, unreadable or truncated bag, or one without the input
      // topics: empty report files would look like a result.
      ROS_WARN(
          "deformation_estimator: no point was ever measured (history '%s'); no reports written to "
          "%s "
          "(was the bag empty, unreadable, or without the topics %s?)",
          database_.c_str(), report_dir_.c_str(), TopicList().c_str());
    } else if (estimator_ && report_on_shutdown_ && !report_dir_.empty()) {
      try {
        const auto files = WriteAllReports("", report_formats_);
        ROS_INFO("deformation_estimator: wrote %zu report file(s) to %s at shutdown", files.size(),
                 report_dir_.c_str());
      } catch (const std::exception& e) {
        ROS_ERROR("deformation_estimator: reports at shutdown failed: %s", e.what());
      }
    }
  }

 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    deformation::EstimatorOptions options;
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh, &options); })) {
      NODELET_ERROR("deformation_estimator: %s; not advertising", error->c_str());
      ReportSetUpFailure("parameters rejected: " + *error);
      return;
    }
    if (const auto error = ros_adapters::SetUpError([&] {
          if (!database_.empty()) history_ = std::make_unique<deformation::History>(database_);
          estimator_ = std::make_unique<deformation::Estimator>(options, history_.get());
        })) {
      NODELET_ERROR(
          "deformation_estimator: %s; refusing to start on it (nothing was written to it); not "
          "advertising",
          error->c_str());
      estimator_.reset();
      history_.reset();
      ReportSetUpFailure("history database refused: " + *error);
      return;
    }
    const deformation::Snapshot resumed = estimator_->GetSnapshot();
    LogResumed(resumed);
    Advertise(pnh);
    Subscribe(pnh);
    StartTimers(nh, pnh);
    if (!resumed.points.empty()) {
      std_msgs::Header h;
      h.frame_id = frame_id_;
      h.stamp = ros::Time(resumed.stamp);
      Publish(resumed, h);
    }
  }

  void LogResumed(const deformation::Snapshot& resumed) {
    if (history_) {
      NODELET_INFO(
          "deformation_estimator: history '%s': %zu point(s) resumed, reference epoch %u (stamp "
          "%.3f)",
          database_.c_str(), resumed.points.size(), resumed.reference_epoch,
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
    if (enable_set_reference_epoch_)
      reference_srv_ = pnh.advertiseService("set_reference_epoch",
                                           &DeformationEstimatorNodelet::OnSetReference, this);
    if (enable_export_report_)
      export_srv_ =
          pnh.advertiseService("export_report", &DeformationEstimatorNodelet::OnExport, this);
  }

  // Relative input topics are the node's own (/deformation_estimator/displacements),
  // like its outputs; the graphs give absolute ones.
  void Subscribe(ros::NodeHandle& nh) {
    for (const std::string& topic : input_topics_) {
      const boost::function<void(const slope_monitor::PointDisplacementArray::ConstPtr&)> callback =
          [this, topic](const slope_monitor::PointDisplacementArray::ConstPtr& msg) {
            OnDisplacements(msg, topic);
          };
      subscribers_.push_back(
          nh.subscribe<slope_monitor::PointDisplacementArray>(topic, 64, callback));
    }
    for (const std::string& topic : area_topics_) {
      const boost::function<void(const slope_monitor::ChangeAreaArray::ConstPtr&)> callback =
          [this, topic](const slope_monitor::ChangeAreaArray::ConstPtr& msg) {
            OnAreas(*msg, topic);
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
    if (order_timeout_ > 0.0) {
      order_ = std::make_unique<InputOrder<Incoming>>(input_topics_);
      order_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                        [this](const ros::WallTimerEvent&) { OnOrderTimer(); });
      // The end of a replay (ros/setup.h): what waits for a later stamp of
      // another input is fused (and published).
      end_sub_ = ros_adapters::SubscribeEndOfInput(nh, ros_adapters::kEndOfFusion, [this] {
        std::lock_guard<std::mutex> lock(mutex_);
        for (auto& r : order_->Flush()) Fuse(r.item, r.input, true);
      });
    }
    if (report_interval_ > 0.0 && !report_dir_.empty()) {
      report_timer_ = nh.createWallTimer(ros::WallDuration(report_interval_),
                                         [this](const ros::WallTimerEvent&) {
                                           std::lock_guard<std::mutex> lock(mutex_);
                                           WriteReportsNow("on the report timer");
                                         });
    }
  }

  // A node that cannot do its job says so: ERROR on /diagnostics every
  // second until it is restarted with the cause fixed.
  void ReportSetUpFailure(const std::string& cause) {
    setup_error_ = cause;
    updater_ =
        std::make_unique<diagnostic_updater::Updater>(getNodeHandle(), getPrivateNodeHandle());
    updater_->setHardwareID("deformation_estimator");
    updater_->add("deformation_estimator", this, &DeformationEstimatorNodelet::Diagnose);
    diag_timer_ = getNodeHandle().createWallTimer(
        ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->force_update(); });
  }

  std::string TopicList() const {
    std::string t;
    for (const std::string& x : input_topics_) t += (t.empty() ? "" : ", ") + x;
    return t;
  }

  void ReadParameters(ros::NodeHandle& pnh, deformation::EstimatorOptions* o) {
    ros_adapters::ParamReader p(pnh);
    ros_adapters::EstimatorParameters e = ros_adapters::ReadEstimatorParameters(p);
    *o = e.options;
    input_topics_ = e.input_topics;
    area_topics_ = e.area_topics;
    frame_id_ = e.frame_id;
    database_ = e.database;
    report_dir_ = e.report_dir;
    report_on_shutdown_ = e.report_on_shutdown;
    report_formats_ = e.report_formats;
    enable_export_report_ = e.enable_export_report;
    enable_set_reference_epoch_ = e.enable_set_reference_epoch;
    report_options_ = e.report;
    marker_options_ = e.markers;
    report_interval_ = e.report_interval;
    order_timeout_ = e.order_timeout;
    report_on_alert_change_ = e.report_on_alert_change;
    plot_options_ = e.plot;
    thresholds_ = o->alerts.thresholds;
    if (e.site) StartHook(*e.site);
  }

  // The site file's notification hook (deformation/alert_hook.h), when it names one.
  void StartHook(const io::SiteFile& site) {
    site_name_ = site.name;
    if (!site.notification.hook.empty()) {
      hook_ = std::make_unique<deformation::AlertHook>(
          site.notification, [](bool error, const std::string& m) {
            if (error) {
              ROS_ERROR("deformation_estimator: %s", m.c_str());
            } else {
              ROS_INFO("deformation_estimator: %s", m.c_str());
            }
          });
    }
    NODELET_INFO("deformation_estimator: site '%s' (notification hook: %s)", site.name.c_str(),
                 site.notification.hook.empty() ? "none" : site.notification.hook.c_str());
  }

  // Caller holds mutex_. The pictures: deformation/plot_report.h.
  std::vector<std::string> WriteAllReports(const std::string& subfolder,
                                           const std::vector<std::string>& formats) {
    return deformation::WriteAllReports(*estimator_, history_ ? database_ : "", plot_options_,
                                        report_dir_, subfolder, formats, report_options_);
  }

  // Caller holds mutex_.
  void WriteReportsNow(const char* why) {
    if (!estimator_ || report_dir_.empty() || estimator_->GetSnapshot().points.empty()) return;
    try {
      const auto files = WriteAllReports("", report_formats_);
      NODELET_INFO("deformation_estimator: wrote %zu report file(s) to %s %s", files.size(),
                   report_dir_.c_str(), why);
    } catch (const std::exception& e) {
      last_problem_ = e.what();
      NODELET_ERROR("deformation_estimator: reports %s failed: %s", why, e.what());
    }
  }

  // A message as it arrived, validated; `fuse` false when every entry was rejected.
  struct Incoming {
    slope_monitor::PointDisplacementArray valid;
    bool fuse = true;
  };

  void OnDisplacements(const slope_monitor::PointDisplacementArray::ConstPtr& msg,
                       const std::string& topic) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++messages_;
    Incoming in;
    in.valid = validator_.Filter(*msg, topic, ros::WallTime::now().toSec());
    for (const std::string& problem : validator_.last_problems()) {
      NODELET_WARN_THROTTLE(10.0, "deformation_estimator: rejected %s", problem.c_str());
      last_problem_ = problem;
    }
    in.fuse = !(in.valid.displacements.empty() && !msg->displacements.empty());
    if (!order_) {
      Fuse(in, topic, true);
      return;
    }
    // In stamp order across the inputs (core/common/input_order.h).
    for (auto& r :
         order_->Add(topic, msg->header.stamp.toSec(), std::move(in), ros::WallTime::now().toSec()))
      Fuse(r.item, r.input, true);
  }

  // Live: a batch that waited order_timeout for a silent input is fused without it.
  void OnOrderTimer() {
    if (!ros_adapters::LiveTimeouts()) return;  // replay: the destructor flushes
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::string> given_up;
    for (auto& r : order_->Expire(ros::WallTime::now().toSec(), order_timeout_, &given_up))
      Fuse(r.item, r.input, true);
    std::string names;
    for (const std::string& t : given_up) names += (names.empty() ? "'" : ", '") + t + "'";
    // Said when the inputs given up on change (a live camera graph gives up
    // on the adjuster between its epochs, hours apart: once, not every time).
    if (!names.empty() && names != given_up_names_)
      NODELET_WARN(
          "deformation_estimator: gave up waiting for %s (nothing newer for order_timeout %.0f s); "
          "fused the other inputs' batches without it",
          names.c_str(), order_timeout_);
    if (!names.empty()) given_up_names_ = names;
  }

  // Caller holds mutex_.
  void Fuse(const Incoming& in, const std::string& topic, bool publish) {
    if (!in.fuse) return;
    try {
      const deformation::BatchSummary s =
          estimator_->AddBatch(ros_adapters::FromMsg(in.valid, topic));
      accepted_ += s.accepted;
      refused_ += s.refused;
      for (const std::string& m : s.messages) {
        NODELET_WARN_THROTTLE(10.0, "deformation_estimator: topic '%s': %s", topic.c_str(),
                              m.c_str());
        last_problem_ = m;
      }
      if (!publish) return;
      std_msgs::Header h = in.valid.header;
      h.frame_id = frame_id_;
      Publish(estimator_->GetSnapshot(), h);
    } catch (const Error& e) {
      ++errors_;
      last_problem_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "deformation_estimator: topic '%s': %s; message dropped",
                             topic.c_str(), e.what());
    }
  }

  // Areas of significant surface change of one epoch (source surface).
  void OnAreas(const slope_monitor::ChangeAreaArray& msg, const std::string& topic) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++messages_;
    try {
      if (!estimator_->AddAreas(ros_adapters::AreaBatchFromMsg(msg, topic))) {
        NODELET_WARN("deformation_estimator: topic '%s': areas of epoch %u are not newer than the last; ignored",
                     topic.c_str(), msg.epoch);
        return;
      }
      std_msgs::Header h = msg.header;
      h.frame_id = frame_id_;
      Publish(estimator_->GetSnapshot(), h);
    } catch (const Error& e) {
      ++errors_;
      last_problem_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "deformation_estimator: topic '%s': %s; message dropped", topic.c_str(), e.what());
    }
  }

  void Publish(const deformation::Snapshot& s, const std_msgs::Header& h) {
    const std::vector<deformation::AlertChange> changes = deformation::AnnounceAlertChanges(
        s, site_name_, &alert_changes_, hook_.get(),
        [this](deformation::LogLevel level, const std::string& text) {
          if (level == deformation::LogLevel::kError) {
            NODELET_ERROR("deformation_estimator: %s", text.c_str());
          } else if (level == deformation::LogLevel::kWarn) {
            NODELET_WARN("deformation_estimator: %s", text.c_str());
          } else {
            NODELET_INFO("deformation_estimator: %s", text.c_str());
          }
        });
    last_alert_ = s.alert;
    num_points_ = s.points.size();
    if (report_on_alert_change_ && !changes.empty()) WriteReportsNow("on an alert-level change");
    deformation_pub_.publish(ros_adapters::ToMsg(s, h));
    if (markers_pub_.getNumSubscribers() > 0) markers_pub_.publish(ros_adapters::ToMarkers(s, h, marker_options_));
    if (points_pub_.getNumSubscribers() > 0) points_pub_.publish(ros_adapters::ToCloud(s, h));
    alerts_pub_.publish(ros_adapters::ToAlerts(s, h));
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req,
                      slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      res.reference_epoch = estimator_->SetReferenceEpoch(req.epoch, req.use_latest);
      res.success = true;
      res.message = Message("reference epoch is now ", res.reference_epoch);
      const deformation::Snapshot s = estimator_->GetSnapshot();
      std_msgs::Header h;
      h.frame_id = frame_id_;
      h.stamp = ros::Time(s.stamp);
      Publish(s, h);
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
      if (report_dir_.empty())
        throw InvalidArgument(
            "parameter 'report_dir' is empty: export_report writes only inside it");
      res.files = WriteAllReports(req.output_dir, req.formats);
      res.success = true;
      res.message =
          Message("wrote ", res.files.size(), " file(s) to ", report_dir_, "/", req.output_dir);
    } catch (const std::exception& e) {
      res.success = false;
      res.files.clear();  // never present a partial set as complete
      res.message = e.what();
      last_problem_ = e.what();
    }
    return true;
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!setup_error_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "not running: " + setup_error_);
      stat.add("database", database_.empty() ? "(none)" : database_);
      return;
    }
    if (errors_ > 0 && !last_problem_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropped messages: " + last_problem_);
    } else {
      stat.summary(
          diagnostic_msgs::DiagnosticStatus::OK,
          Message(num_points_, " points, slope alert ", deformation::AlertName(last_alert_)));
    }
    stat.add("messages", messages_);
    stat.add("measurements accepted", accepted_);
    stat.add("measurements refused", refused_);
    stat.add("messages dropped", errors_);
    for (const auto& [reason, count] : validator_.rejected())
      stat.add("rejected: " + reason, count);
    stat.add("database", database_.empty() ? "(none)" : database_);
    stat.add("last problem", last_problem_);
  }

  std::mutex mutex_;
  std::vector<std::string> input_topics_;
  std::vector<std::string> area_topics_;  // ChangeAreaArray topics (dense step)
  std::string frame_id_, database_, report_dir_;
  bool report_on_shutdown_ = true;
  double report_interval_ = 0.0;                  // [s] live mode: reports on a wall timer; 0 = off
  bool report_on_alert_change_ = false;           // live mode: reports at every alert-level change
  std::string site_name_;                         // from the site file ("" without one)
  std::unique_ptr<deformation::AlertHook> hook_;  // the site's notification hook (none without one)
  ros::WallTimer report_timer_;
  double order_timeout_ = 0.0;  // [s] wall, from the parameter order_timeout; 0 = arrival order
  std::unique_ptr<InputOrder<Incoming>> order_;  // null with order_timeout 0
  ros::Subscriber end_sub_;  // replay only: the end of the input
  ros::WallTimer order_timer_;
  std::string given_up_names_;                   // the inputs the order last gave up on
  deformation::PlotReportOptions plot_options_;  // script "" = OpenCV pictures
  deformation::Thresholds thresholds_;           // drawn in the plots
  bool enable_export_report_ = true, enable_set_reference_epoch_ = true;
  std::vector<std::string> report_formats_;
  deformation::ReportOptions report_options_;
  ros_adapters::MarkerOptions marker_options_;
  ros_adapters::MessageValidator validator_;
  std::unique_ptr<deformation::History> history_;
  std::unique_ptr<deformation::Estimator> estimator_;
  std::vector<ros::Subscriber> subscribers_;
  ros::Publisher deformation_pub_, markers_pub_, points_pub_, alerts_pub_;
  ros::ServiceServer reference_srv_, export_srv_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  uint64_t messages_ = 0, accepted_ = 0, refused_ = 0, errors_ = 0;
  size_t num_points_ = 0;
  deformation::AlertLevel last_alert_ = deformation::AlertLevel::kNone;
  deformation::AlertChangeTracker alert_changes_;  // logs each point's level change (WARN / ERROR)
  std::string last_problem_;
  std::string setup_error_;  // why the node is not running; "" when it is
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DeformationEstimatorNodelet, nodelet::Nodelet)
