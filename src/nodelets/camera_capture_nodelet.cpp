// camera_capture: fixed cameras (V4L2), UAV photo folders and video files into
// image_raw + camera_info, GNSS fix and position prior, epoch markers.
// Thin wrapper: parameters -> core options (capture::*), a worker thread that
// steps the core source, FramePublisher (ros/capture_conversions.h) to publish.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

#include <camera_info_manager/camera_info_manager.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/capture_conversions.h"
#include "slope_monitor/ros/capture_parameters.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {

class CameraCaptureNodelet : public nodelet::Nodelet {
 public:
  ~CameraCaptureNodelet() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      running_ = false;
    }
    wake_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      FailSetUp(*error, "parameters rejected: " + *error);
      return;
    }
    camera_info_manager_ =
        std::make_unique<camera_info_manager::CameraInfoManager>(nh, camera_name_);
    if (!camera_info_url_.empty()) {
      if (!camera_info_manager_->validateURL(camera_info_url_) ||
          !camera_info_manager_->loadCameraInfo(camera_info_url_) ||
          !camera_info_manager_->isCalibrated()) {
        FailSetUp("parameter '" + pnh.resolveName("camera_info_url") + "' = '" + camera_info_url_ +
                      "' cannot be loaded as a calibration",
                  "camera_info_url '" + camera_info_url_ + "' is not a calibration");
        return;
      }
      publisher_options_.has_camera_info = true;
      publisher_options_.camera_info = camera_info_manager_->getCameraInfo();
    }

    image_transport::ImageTransport it(nh);
    // A folder or video is published once: a recorder that falls behind
    // (a loaded machine, 36 MB photos) must not lose a photo to the
    // publisher's queue (4 lost the oldest of eight 12 MP photos at load 5).
    camera_pub_ = it.advertiseCamera("image_raw", source_kind_ == "device" ? 4 : 32);
    epoch_pub_ = nh.advertise<slope_monitor::EpochMarker>("epoch", 16, true);
    if (source_kind_ == "folder") {
      fix_pub_ = nh.advertise<sensor_msgs::NavSatFix>("gnss/fix", 16);
      if (publisher_options_.has_site_origin) {
        prior_pub_ = nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("position_prior", 16);
      }
      if (!publisher_options_.picks.empty())  // the site's gcp list
        picks_pub_ = nh.advertise<slope_monitor::TargetObservationArray>("picks", 32);
    }
    if (source_kind_ == "device")
      trigger_srv_ = nh.advertiseService("trigger", &CameraCaptureNodelet::OnTrigger, this);

    ros_adapters::CaptureOutputs out;
    out.image = [this](const sensor_msgs::ImagePtr& img, const sensor_msgs::CameraInfoPtr& info) {
      camera_pub_.publish(img, info);
      ++published_;
    };
    out.fix = [this](const sensor_msgs::NavSatFix& f) { fix_pub_.publish(f); };
    out.prior = [this](const geometry_msgs::PoseWithCovarianceStamped& p) {
      prior_pub_.publish(p);
    };
    out.epoch = [this](const slope_monitor::EpochMarker& m) { epoch_pub_.publish(m); };
    out.picks = [this](const slope_monitor::TargetObservationArray& m) { picks_pub_.publish(m); };
    out.warn = [this](const std::string& w) {
      NODELET_WARN("camera_capture: %s", w.c_str());
      std::lock_guard<std::mutex> lock(mutex_);
      last_warning_ = w;
      if (w.rfind("skipped ", 0) == 0) ++skipped_;
    };
    try {
      publisher_ = std::make_unique<ros_adapters::FramePublisher>(publisher_options_, out);
    } catch (const Error& e) {
      FailSetUp(e.what(), e.what());
      return;
    }

    diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    diagnostics_->setHardwareID(source_description_);
    diagnostics_->add("capture", this, &CameraCaptureNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(
        ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { diagnostics_->update(); });

    running_ = true;
    worker_ = std::thread(&CameraCaptureNodelet::Run, this);
  }

  // The setup failed: a live camera stays loaded, advertises nothing and
  // names the cause on /diagnostics (ros/setup.h); a folder or video run to
  // its end (exit_at_end, camera_capture.launch) has nothing to wait for, so
  // the process ends with status 1 and the recording script sees it.
  void FailSetUp(const std::string& message, const std::string& cause) {
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    bool exit_at_end = ros_adapters::CaptureParameters{}.exit_at_end;
    pnh.getParam("exit_at_end", exit_at_end);  // also when the other parameters were refused
    if (exit_at_end) {
      NODELET_FATAL("camera_capture: %s; exiting (exit_at_end)", message.c_str());
      ros_adapters::EndProcess(1);
      return;
    }
    NODELET_ERROR("camera_capture: %s; not advertising", message.c_str());
    setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
        getNodeHandle(), pnh, "camera_capture", cause);
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    const ros_adapters::CaptureParameters c =
        ros_adapters::ReadCaptureParameters(p, getNodeHandle().getNamespace());
    source_kind_ = c.source;
    camera_name_ = c.camera_name;
    camera_info_url_ = c.camera_info_url;
    encoding_ = c.encoding;
    source_description_ = c.source_description;
    rate_ = c.rate;
    start_delay_ = c.start_delay;
    retry_interval_ = c.retry_interval;
    subscriber_wait_ = c.subscriber_wait;
    exit_at_end_ = c.exit_at_end;
    continuous_ = c.continuous;
    folder_ = c.folder;
    video_ = c.video;
    device_ = c.device;
    schedule_ = c.schedule;
    epochs_ = c.epochs;
    publisher_options_ = c.publisher;
  }

  bool OnTrigger(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!device_open_) {
      res.success = false;
      res.message = source_description_ + " is not open: " + status_;
      return true;
    }
    trigger_pending_ = true;
    wake_.notify_all();
    res.success = true;
    res.message = "capture of " + std::to_string(schedule_.frames_per_epoch) + " frame(s) queued";
    return true;
  }

  // Sleeps up to `seconds` (or until shutdown / a trigger). Returns false on shutdown.
  bool Wait(double seconds, bool wake_on_trigger) {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait_for(lock, std::chrono::duration<double>(seconds),
                   [&] { return !running_ || (wake_on_trigger && trigger_pending_); });
    return running_;
  }

  void SetStatus(const std::string& s) {
    std::lock_guard<std::mutex> lock(mutex_);
    status_ = s;
  }

  void Run() {
    if (source_kind_ != "device") {
      // A folder or video is published once: wait for a subscriber (rosbag
      // record, the graph) so that the first photos are not lost.
      const auto deadline =
          std::chrono::steady_clock::now() + std::chrono::duration<double>(subscriber_wait_);
      while (camera_pub_.getNumSubscribers() == 0 && std::chrono::steady_clock::now() < deadline)
        if (!Wait(0.1, false)) return;
    }
    if (!Wait(start_delay_, false)) return;
    if (source_kind_ == "device") {
      RunDevice();
      return;
    }
    std::unique_ptr<capture::FrameSource> source;
    try {
      if (source_kind_ == "folder") {
        auto folder = std::make_unique<capture::FolderSource>(folder_);
        for (const auto& w : folder->exif_warnings()) {
          NODELET_WARN("camera_capture: %s (using the file time)", w.reason.c_str());
        }
        for (const auto& w : folder->left_out()) {
          NODELET_WARN("camera_capture: left out %s: %s", w.name.c_str(), w.reason.c_str());
          std::lock_guard<std::mutex> lock(mutex_);
          ++skipped_;
          last_warning_ = "left out " + w.name + ": " + w.reason;
        }
        source = std::move(folder);
      } else {
        source = std::make_unique<capture::VideoSource>(video_);
      }
    } catch (const Error& e) {
      SetStatus(e.what());
      if (exit_at_end_) {  // nothing to publish
        NODELET_FATAL("camera_capture: %s; exiting (exit_at_end)", e.what());
        ros_adapters::EndProcess(1);
      } else {
        NODELET_ERROR("camera_capture: %s", e.what());
      }
      return;
    }
    SetStatus("publishing " + source->Describe());
    NODELET_INFO("camera_capture: publishing %s at %.3g Hz", source->Describe().c_str(), rate_);
    capture::EpochTracker tracker(epochs_);
    while (Wait(1.0 / rate_, false)) {
      try {
        if (publisher_->Step(source.get(), &tracker, true) ==
            ros_adapters::FramePublisher::StepResult::kEnd) {
          NODELET_INFO("camera_capture: end of %s: %lu published, %lu skipped",
                       source->Describe().c_str(), static_cast<unsigned long>(published_.load()),
                       static_cast<unsigned long>(source->skipped_count()));
          SetStatus("finished " + source->Describe());
          if (exit_at_end_) {
            // The last messages reach the subscribers, then the node ends
            // (camera_capture.launch: a folder or video is done).
            if (published_.load() == 0) {
              NODELET_FATAL("camera_capture: no image of %s could be published; exiting",
                            source->Describe().c_str());
              ros_adapters::EndProcess(1);
              return;
            }
            if (Wait(5.0, false)) NODELET_INFO("camera_capture: exiting (exit_at_end)");
            ros::requestShutdown();
          }
          return;
        }
      } catch (const std::exception& e) {
        NODELET_ERROR_THROTTLE(5.0, "camera_capture: %s", e.what());
      }
    }
  }

  void RunDevice() {
    capture::DeviceSource source(device_);
    capture::CaptureSchedule schedule(schedule_);
    capture::EpochOptions eo = epochs_;
    if (!continuous_) eo.gap = 1e12;  // epochs are the scheduled bursts
    capture::EpochTracker tracker(eo);
    while (running_) {
      if (!source.IsOpen()) {
        try {
          source.Open();
          for (const auto& w : source.warnings()) NODELET_WARN("camera_capture: %s", w.c_str());
          NODELET_INFO("camera_capture: opened %s", source.Describe().c_str());
          std::lock_guard<std::mutex> lock(mutex_);
          device_open_ = true;
          status_ = "open";
        } catch (const Error& e) {
          {
            std::lock_guard<std::mutex> lock(mutex_);
            device_open_ = false;
            status_ = e.what();
            ++open_failures_;
          }
          NODELET_ERROR_THROTTLE(30.0, "camera_capture: %s; retrying every %.3g s", e.what(),
                                 retry_interval_);
          if (!Wait(retry_interval_, false)) return;
          continue;
        }
      }
      try {
        if (continuous_) {
          publisher_->Step(&source, &tracker, false);
          continue;
        }
        // Wait for the next scheduled capture or a trigger.
        const double now = ros::WallTime::now().toSec();
        const std::optional<double> next = schedule.NextCapture(now);
        const double wait = next ? *next - now : 3600.0;
        {
          std::unique_lock<std::mutex> lock(mutex_);
          wake_.wait_for(lock, std::chrono::duration<double>(std::min(wait, 1.0)),
                         [&] { return !running_ || trigger_pending_; });
          if (!running_) return;
          const bool due = next && ros::WallTime::now().toSec() >= *next;
          if (!due && !trigger_pending_) continue;
          trigger_pending_ = false;
        }
        for (int i = 0; i < schedule_.frames_per_epoch; ++i)
          publisher_->Step(&source, &tracker, false);
        if (auto end = tracker.Close()) publisher_->PublishEpoch(*end);
      } catch (const Error& e) {
        if (auto end = tracker.Close()) publisher_->PublishEpoch(*end);
        NODELET_ERROR_THROTTLE(5.0, "camera_capture: %s", e.what());
        std::lock_guard<std::mutex> lock(mutex_);
        device_open_ = source.IsOpen();
        status_ = e.what();
      }
    }
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    const uint64_t skipped = skipped_;
    if (source_kind_ == "device" && !device_open_) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "device not open: " + status_);
    } else if (skipped > 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "skipped unreadable images");
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, status_.empty() ? "running" : status_);
    }
    stat.add("source", source_description_);
    stat.add("status", status_);
    stat.add("published", published_.load());
    stat.add("skipped", skipped);
    stat.add("last warning", last_warning_);
    stat.add("device open failures", open_failures_);
  }

  // Parameters.
  std::string source_kind_, camera_name_, camera_info_url_, encoding_, source_description_;
  // From ros_adapters::CaptureParameters (its defaults and units).
  double rate_ = 0.0, start_delay_ = 0.0, retry_interval_ = 0.0;
  double subscriber_wait_ = 0.0;
  bool exit_at_end_ = false;
  bool continuous_ = false;
  capture::FolderSourceOptions folder_;
  capture::VideoSourceOptions video_;
  capture::DeviceSourceOptions device_;
  capture::ScheduleOptions schedule_;
  capture::EpochOptions epochs_;
  ros_adapters::FramePublisherOptions publisher_options_;

  // ROS.
  std::unique_ptr<camera_info_manager::CameraInfoManager> camera_info_manager_;
  image_transport::CameraPublisher camera_pub_;
  ros::Publisher epoch_pub_, fix_pub_, prior_pub_, picks_pub_;
  ros::ServiceServer trigger_srv_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer diag_timer_;
  std::unique_ptr<ros_adapters::FramePublisher> publisher_;

  // Worker.
  std::thread worker_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::atomic<bool> running_{false};
  bool trigger_pending_ = false;
  bool device_open_ = false;
  uint64_t open_failures_ = 0;
  uint64_t skipped_ = 0;
  std::atomic<uint64_t> published_{0};
  std::string status_, last_warning_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::CameraCaptureNodelet, nodelet::Nodelet)
