// dense_epoch (launched as `dense_matcher` in the replay and live graphs):
// one dense surface per adjusted epoch and its DoD against the reference
// epoch with a level of detection (ros_adapters::DenseEpochStep:
// core/dense/epoch_photos.h, epoch_surface.h, surface_series.h, dem_change.h).
//
// Thin wrapper: the photos and camera_info of the surface cameras
// (/<camera>/camera/image_raw, camera_info) and the AdjustmentSolutions on
// `solution` go to the step's photo collector, which decides by message when
// an epoch has its photos (in whichever order they come; the wall clock only
// for the live photo_wait time-out, polled once a second: a replay's clock
// stops with the bag, a lost photo must not hold the last epoch for ever;
// photos come within a fraction of a wall second of their solution at any
// rate). A worker thread of its
// own measures the complete epochs, so neither the bundle adjuster nor the
// estimator waits for it. Outputs: a latched PointCloud2 `surface_cloud` in
// `site` per epoch (fields x y z rgb sigma_z change lod), the colour scale
// of `change` beside it (MarkerArray `change_legend`, latched) and, with
// report_dir, what process_flight writes per flight (dense::SurfaceSeries):
// surface_eNN.tif, ortho_eNN.tif, cloud_eNN.ply, change_eNN.tif and
// surface_report_eNN.json / .md (co-registration, volumes); per later epoch the
// polygons of significant change (ChangeAreaArray `change_areas`, latched)
// for the deformation estimator. A failing step is
// named (log, diagnostics) and the epoch's other outputs are kept.
#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/ros/dense_epoch_step.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class DenseEpochNodelet : public nodelet::Nodelet {
 public:
  ~DenseEpochNodelet() override {
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      stop_ = true;
    }
    queue_cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    ros_adapters::DenseEpochParameters params;
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          params = ros_adapters::ReadDenseEpochParameters(p);
          step_ = std::make_unique<ros_adapters::DenseEpochStep>(params);
        })) {
      NODELET_ERROR("dense_matcher: %s; not advertising", error->c_str());
      return;
    }
    cloud_pub_ = nh.advertise<sensor_msgs::PointCloud2>("surface_cloud", 1, true);
    areas_pub_ = nh.advertise<slope_monitor::ChangeAreaArray>("change_areas", 2, true);
    legend_pub_ = nh.advertise<visualization_msgs::MarkerArray>("change_legend", 1, true);
    // A queue as deep as the photos the collector may hold: the transport
    // never drops a photo of a flight that fits the memory limit.
    const uint32_t queue = static_cast<uint32_t>(params.photos.max_photos);
    for (const std::string& c : params.cameras) {
      if (!step_->Uses(c)) continue;
      subs_.push_back(nh.subscribe<sensor_msgs::Image>(
          "/" + c + "/camera/image_raw", queue, [this, c](const sensor_msgs::ImageConstPtr& m) {
            Collect([&] { return step_->OnImage(c, *m, ros::WallTime::now().toSec()); });
          }));
      subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          "/" + c + "/camera/camera_info", queue,
          [this, c](const sensor_msgs::CameraInfoConstPtr& m) {
            Collect([&] {
              step_->OnCameraInfo(c, *m);
              return std::vector<dense::PhotoEpoch>();
            });
          }));
    }
    subs_.push_back(nh.subscribe<slope_monitor::AdjustmentSolution>(
        "solution", 16, [this](const slope_monitor::AdjustmentSolutionConstPtr& m) {
          Collect([&] { return step_->OnSolution(*m, ros::WallTime::now().toSec()); });
        }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("dense_matcher");
    updater_->add("dense_matcher", this, &DenseEpochNodelet::Diagnose);
    timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
      if (ros_adapters::LiveTimeouts())
        Collect([&] { return step_->Poll(ros::WallTime::now().toSec()); });
      updater_->update();
    });
    worker_ = std::thread([this] { Work(); });
    // The end of a replay (ros/setup.h): the epochs held are measured.
    end_sub_ = ros_adapters::SubscribeEndOfInput(
        nh, ros_adapters::kEndOfSurfaces, [this] { Collect([&] { return step_->Finish(); }); });
  }

  // Runs one collector call; complete epochs go to the worker.
  template <typename F>
  void Collect(F call) {
    std::vector<dense::PhotoEpoch> done;
    {
      std::lock_guard<std::mutex> lock(collector_mutex_);
      try {
        done = call();
      } catch (const std::exception& e) {
        Fail(e.what());
      }
      Log(step_->TakeLog());
      photos_held_ = step_->photos().photos_held();
      megabytes_held_ = step_->photos().megabytes_held();
    }
    if (done.empty()) return;
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      for (dense::PhotoEpoch& e : done) jobs_.push_back(std::move(e));
    }
    queue_cv_.notify_one();
  }

  void Work() {
    for (;;) {
      dense::PhotoEpoch job;
      {
        std::unique_lock<std::mutex> lock(queue_mutex_);
        queue_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
        if (stop_) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      const ros_adapters::DenseEpochOutput out = step_->Measure(
          job, [this](const std::string& s) { NODELET_INFO("dense_matcher: %s", s.c_str()); });
      Log(out.log);
      if (out.cloud) cloud_pub_.publish(*out.cloud);
      if (out.legend) legend_pub_.publish(*out.legend);
      if (out.areas) areas_pub_.publish(*out.areas);
      std::lock_guard<std::mutex> lock(state_mutex_);
      if (out.cloud) ++epochs_;
      for (const auto& line : out.log)
        if (line.level == ros_adapters::LogLine::kInfo) last_summary_ = line.text;
    }
  }

  void Log(const std::vector<ros_adapters::LogLine>& lines) {
    for (const ros_adapters::LogLine& l : lines) {
      if (l.level >= ros_adapters::LogLine::kError) {
        Fail(l.text);
      } else if (l.level == ros_adapters::LogLine::kWarn) {
        NODELET_WARN("dense_matcher: %s", l.text.c_str());
      } else {
        NODELET_INFO("dense_matcher: %s", l.text.c_str());
      }
    }
  }

  void Fail(const std::string& what) {
    NODELET_ERROR("dense_matcher: %s", what.c_str());
    std::lock_guard<std::mutex> lock(state_mutex_);
    ++failures_;
    last_error_ = what;
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    stat.summary(failures_ > 0 ? diagnostic_msgs::DiagnosticStatus::WARN
                               : diagnostic_msgs::DiagnosticStatus::OK,
                 epochs_ > 0 ? "measuring epochs" : "waiting for an adjusted epoch");
    stat.add("epochs measured", epochs_);
    stat.add("failures", failures_);
    stat.add("photos held", photos_held_.load());
    stat.add("megabytes held", megabytes_held_.load());
    stat.add("last report", last_summary_);
    stat.add("last error", last_error_);
  }

  std::unique_ptr<ros_adapters::DenseEpochStep> step_;
  ros::Publisher cloud_pub_, areas_pub_, legend_pub_;
  std::vector<ros::Subscriber> subs_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer timer_;
  std::mutex collector_mutex_;  // step_'s collection calls
  std::atomic<int> photos_held_{0};
  std::atomic<double> megabytes_held_{0.0};
  std::mutex queue_mutex_;  // jobs_, stop_
  std::condition_variable queue_cv_;
  std::deque<dense::PhotoEpoch> jobs_;
  bool stop_ = false;
  std::thread worker_;       // step_'s Measure
  ros::Subscriber end_sub_;  // replay only: the end of the input
  std::mutex state_mutex_;   // counters and reports
  int epochs_ = 0, failures_ = 0;
  std::string last_summary_, last_error_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DenseEpochNodelet, nodelet::Nodelet)
