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
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/capture_conversions.h"
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
      NODELET_ERROR("camera_capture: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(nh, pnh, "camera_capture",
                                                                               "parameters rejected: " + *error);
      return;
    }
    camera_info_manager_ = std::make_unique<camera_info_manager::CameraInfoManager>(nh, camera_name_);
    if (!camera_info_url_.empty()) {
      if (!camera_info_manager_->validateURL(camera_info_url_) ||
          !camera_info_manager_->loadCameraInfo(camera_info_url_) || !camera_info_manager_->isCalibrated()) {
        NODELET_ERROR("camera_capture: parameter '%s' = '%s' cannot be loaded as a calibration; not advertising",
                      pnh.resolveName("camera_info_url").c_str(), camera_info_url_.c_str());
        setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
            nh, pnh, "camera_capture", "camera_info_url '" + camera_info_url_ + "' is not a calibration");
        return;
      }
      publisher_options_.has_camera_info = true;
      publisher_options_.camera_info = camera_info_manager_->getCameraInfo();
    }

    image_transport::ImageTransport it(nh);
    camera_pub_ = it.advertiseCamera("image_raw", 4);
    epoch_pub_ = nh.advertise<slope_monitor::EpochMarker>("epoch", 16, true);
    if (source_kind_ == "folder") {
      fix_pub_ = nh.advertise<sensor_msgs::NavSatFix>("gnss/fix", 16);
      if (publisher_options_.has_site_origin) {
        prior_pub_ = nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("position_prior", 16);
      }
    }
    if (source_kind_ == "device") trigger_srv_ = nh.advertiseService("trigger", &CameraCaptureNodelet::OnTrigger, this);

    ros_adapters::CaptureOutputs out;
    out.image = [this](const sensor_msgs::ImagePtr& img, const sensor_msgs::CameraInfoPtr& info) {
      camera_pub_.publish(img, info);
      ++published_;
    };
    out.fix = [this](const sensor_msgs::NavSatFix& f) { fix_pub_.publish(f); };
    out.prior = [this](const geometry_msgs::PoseWithCovarianceStamped& p) { prior_pub_.publish(p); };
    out.epoch = [this](const slope_monitor::EpochMarker& m) { epoch_pub_.publish(m); };
    out.warn = [this](const std::string& w) {
      NODELET_WARN("camera_capture: %s", w.c_str());
      std::lock_guard<std::mutex> lock(mutex_);
      last_warning_ = w;
      if (w.rfind("skipped ", 0) == 0) ++skipped_;
    };
    try {
      publisher_ = std::make_unique<ros_adapters::FramePublisher>(publisher_options_, out);
    } catch (const Error& e) {
      NODELET_ERROR("camera_capture: %s; not advertising", e.what());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(nh, pnh, "camera_capture", e.what());
      return;
    }

    diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    diagnostics_->setHardwareID(source_description_);
    diagnostics_->add("capture", this, &CameraCaptureNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { diagnostics_->update(); });

    running_ = true;
    worker_ = std::thread(&CameraCaptureNodelet::Run, this);
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    source_kind_ = p.String("source", "device", {"device", "folder", "video"});
    camera_name_ = p.String("camera_name", "camera");
    // The camera's name by the graph's one rule (ros/uav_topics.h): ns /uav/camera is camera uav.
    publisher_options_.source_name =
        p.String("source_name", ros_adapters::CameraOfNamespace(getNodeHandle().getNamespace()));
    const std::string site_file = p.String("site_file", "");
    publisher_options_.frame_id = p.String("frame_id", camera_name_ + "_optical");
    camera_info_url_ = p.String("camera_info_url", "");
    publisher_options_.pixel_size = p.Double("pixel_size", 0.0, 0.0, 1.0, "mm");
    const std::vector<double> interior = p.DoubleList("interior", {});
    const std::string model = p.String("distortion_model", "brown_affinity", {"none", "radial", "brown", "brown_affinity"});
    const int sensor_width = p.Int("sensor_width", 0, 0, 100000, "px");
    const int sensor_height = p.Int("sensor_height", 0, 0, 100000, "px");
    encoding_ = p.String("encoding", "auto", {"auto", "mono8", "bgr8"});
    rate_ = p.Double("rate", 2.0, 0.001, 1000.0, "Hz");
    start_delay_ = p.Double("start_delay", 1.0, 0.0, 3600.0, "s");
    subscriber_wait_ = p.Double("subscriber_wait", 10.0, 0.0, 3600.0, "s");
    exit_at_end_ = p.Bool("exit_at_end", false);

    // Folder.
    folder_.folder = p.String("folder", "");
    folder_.extensions = p.StringList("extensions", folder_.extensions);
    folder_.time_source = p.String("time_source", "exif", {"exif", "file"});
    folder_.clock_offset = p.Double("clock_offset", 0.0, -1e9, 1e9, "s");
    folder_.encoding = encoding_;
    // Video.
    video_.path = p.String("video_file", "");
    video_.start_time = p.Double("video_start_time", -1.0, -1.0, 1e10, "s");
    video_.fps = p.Double("video_fps", 0.0, 0.0, 1000.0, "Hz");
    video_.frame_step = p.Int("frame_step", 1, 1, 100000);
    video_.encoding = encoding_;
    // Device.
    device_.device = p.String("device", "/dev/video0");
    device_.api = p.String("device_api", "v4l2", {"v4l2", "any"});
    device_.width = p.Int("width", 0, 0, 20000, "px");
    device_.height = p.Int("height", 0, 0, 20000, "px");
    device_.fps = p.Double("fps", 0.0, 0.0, 1000.0, "Hz");
    device_.exposure = p.Double("exposure", -1.0, -1.0, 1e7, "device units");
    device_.encoding = encoding_;
    retry_interval_ = p.Double("retry_interval", 5.0, 0.1, 3600.0, "s");
    continuous_ = p.Bool("continuous", false);
    // Schedule.
    schedule_.interval = p.Double("schedule/interval", 600.0, 0.0, 7 * 86400.0, "s");
    schedule_.windows = p.StringList("schedule/windows", {});
    schedule_.utc_offset_hours = p.Double("schedule/utc_offset", 0.0, -14.0, 14.0, "h");
    schedule_.frames_per_epoch = p.Int("schedule/frames_per_epoch", 1, 1, 1000);
    // Epochs.
    epochs_.gap = p.Double("epoch_gap", 600.0, 1e-3, 1e9, "s");
    epochs_.max_duration = p.Double("epoch_max_duration", 0.0, 0.0, 1e9, "s");
    epochs_.first_epoch = static_cast<uint32_t>(p.Int("first_epoch", 0, 0, 1000000000));
    // GNSS.
    const std::vector<double> origin = p.DoubleList("site_origin", {});
    publisher_options_.site_frame = p.String("site_frame", "site");
    publisher_options_.gnss.sigma_horizontal = p.Double("gnss_sigma_horizontal", 5.0, 1e-4, 1e4, "m");
    publisher_options_.gnss.sigma_vertical = p.Double("gnss_sigma_vertical", 10.0, 1e-4, 1e4, "m");
    publisher_options_.gnss.geoid_height = p.Double("geoid_height", 0.0, -200.0, 200.0, "m");
    publisher_options_.attitude_sigma = p.Double("attitude_sigma", 10.0, 0.01, 180.0, "deg");
    p.CheckNoUnknownKeys();
    if (!site_file.empty()) ApplySiteFile(site_file, origin.empty());

    if (!origin.empty()) {
      if (origin.size() != 3) {
        throw ConfigError(Message("parameter '", p.FullKey("site_origin"), "' must be [lat_deg, lon_deg, height_m], got ",
                                  origin.size(), " values"));
      }
      publisher_options_.has_site_origin = true;
      publisher_options_.site_origin = {origin[0], origin[1], origin[2]};
      capture::CheckGeodetic(publisher_options_.site_origin, p.FullKey("site_origin").c_str());
    }
    if (!interior.empty()) {
      if (interior.size() != camera::kNumInterior) {
        throw ConfigError(Message("parameter '", p.FullKey("interior"), "' needs ", camera::kNumInterior,
                                  " values (c x0 y0 k1 k2 k3 p1 p2 b1 b2), got ", interior.size()));
      }
      if (!camera_info_url_.empty()) {
        throw ConfigError(Message("parameters '", p.FullKey("interior"), "' and '", p.FullKey("camera_info_url"),
                                  "' are both set; use one calibration"));
      }
      if (!(publisher_options_.pixel_size > 0.0) || sensor_width <= 0 || sensor_height <= 0) {
        throw ConfigError(Message("parameter '", p.FullKey("interior"), "' needs pixel_size, sensor_width and sensor_height"));
      }
      std::array<double, camera::kNumInterior> a{};
      std::copy(interior.begin(), interior.end(), a.begin());
      try {
        const camera::CameraModel m(camera::Sensor{sensor_width, sensor_height, publisher_options_.pixel_size},
                                    camera::DistortionModelFromName(model), a);
        m.Check();
        publisher_options_.camera_info = ros_adapters::ToMsg(m.ToCameraInfo());
        publisher_options_.has_camera_info = true;
      } catch (const InvalidArgument& e) {
        throw ConfigError(Message("parameter '", p.FullKey("interior"), "': ", e.what()));
      }
    }
    epochs_.Check();
    if (source_kind_ == "folder") {
      folder_.Check();
      source_description_ = "folder " + folder_.folder;
    } else if (source_kind_ == "video") {
      video_.Check();
      source_description_ = "video " + video_.path;
    } else {
      device_.Check();
      schedule_.Check();
      source_description_ = (device_.api == "v4l2" ? "V4L2 " : "camera ") + device_.device;
    }
  }

  // The site file (io::LoadSiteFile): the position priors' origin (a local_enu
  // site's origin, unless site_origin is set) and this camera's pixel size
  // (its entry, by the camera's name, unless pixel_size is set).
  void ApplySiteFile(const std::string& path, bool origin_from_site) {
    const io::SiteFile site = io::LoadSiteFile(path);
    if (origin_from_site) {
      if (site.crs.frame != SiteCrsOptions::Frame::kLocalEnu)
        throw ConfigError(Message(path, ": frame shifted_crs: camera_capture's position priors need a local_enu site "
                                        "(or set site_origin)"));
      const Eigen::Vector3d lon_lat_h = SiteCrs(site.crs).origin_wgs84();
      publisher_options_.has_site_origin = true;
      publisher_options_.site_origin = {lon_lat_h.y(), lon_lat_h.x(), lon_lat_h.z()};
    }
    const io::SiteCamera* camera = site.FindCamera(publisher_options_.source_name);
    if (camera && !(publisher_options_.pixel_size > 0.0)) publisher_options_.pixel_size = camera->pixel_size;
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
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(subscriber_wait_);
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
      NODELET_ERROR("camera_capture: %s", e.what());
      SetStatus(e.what());
      if (exit_at_end_) ros::requestShutdown();  // nothing to publish
      return;
    }
    SetStatus("publishing " + source->Describe());
    NODELET_INFO("camera_capture: publishing %s at %.3g Hz", source->Describe().c_str(), rate_);
    capture::EpochTracker tracker(epochs_);
    while (Wait(1.0 / rate_, false)) {
      try {
        if (publisher_->Step(source.get(), &tracker, true) == ros_adapters::FramePublisher::StepResult::kEnd) {
          NODELET_INFO("camera_capture: end of %s: %lu published, %lu skipped", source->Describe().c_str(),
                       static_cast<unsigned long>(published_.load()),
                       static_cast<unsigned long>(source->skipped_count()));
          SetStatus("finished " + source->Describe());
          if (exit_at_end_) {
            // The last messages reach the subscribers, then the node ends
            // (camera_capture.launch: a folder or video is done).
            if (Wait(2.0, false)) NODELET_INFO("camera_capture: exiting (exit_at_end)");
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
          NODELET_ERROR_THROTTLE(30.0, "camera_capture: %s; retrying every %.3g s", e.what(), retry_interval_);
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
        for (int i = 0; i < schedule_.frames_per_epoch; ++i) publisher_->Step(&source, &tracker, false);
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
  double rate_ = 2.0, start_delay_ = 1.0, retry_interval_ = 5.0;
  double subscriber_wait_ = 10.0;  // [s] folder / video: wait this long at most for a subscriber
  bool exit_at_end_ = false;       // folder / video: end the process after the last frame
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
  ros::Publisher epoch_pub_, fix_pub_, prior_pub_;
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
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics> setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::CameraCaptureNodelet, nodelet::Nodelet)
