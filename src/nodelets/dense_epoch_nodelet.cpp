// dense_epoch (launched as `dense_matcher` in the replay and live graphs):
// one dense surface per adjusted epoch (core/dense/epoch_surface.h) and its
// DoD against the reference epoch with a level of detection
// (core/dense/dem_change.h).
//
// Thin wrapper: images and camera_info of every camera in `cameras` are kept
// (the last max_cached_images per camera; topics /<camera>/camera/image_raw
// and /<camera>/camera/camera_info); each usable AdjustmentSolution on
// `solution` picks the images it oriented (camera name + image stamp), and a
// worker thread of its own measures the epoch, so neither the bundle
// adjuster nor the estimator waits for it. Outputs: a latched PointCloud2
// `surface_cloud` in `site` per epoch (fields x y z rgb sigma_z change lod)
// and, with report_dir, surface_eNN.tif and change_eNN.tif there; per later
// epoch the polygons of significant change (ChangeAreaArray `change_areas`,
// latched) for the deformation estimator. The first
// epoch measured is the reference; its grid is the grid of later epochs.
// A failing step is named (log, diagnostics) and the epoch's other outputs
// are kept: a DoD that fails still leaves the cloud and surface_eNN.tif.
#include <algorithm>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/change_polygons.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/ros/change_area_conversions.h"
#include "slope_monitor/ros/dense_conversions.h"
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
  struct Job {
    std_msgs::Header header;
    dense::EpochSurfaceInput input;
  };

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      NODELET_ERROR("dense_matcher: %s; not advertising", error->c_str());
      return;
    }
    cloud_pub_ = nh.advertise<sensor_msgs::PointCloud2>("surface_cloud", 1, true);
    areas_pub_ = nh.advertise<slope_monitor::ChangeAreaArray>("change_areas", 2, true);
    for (const std::string& c : cameras_) {
      subs_.push_back(nh.subscribe<sensor_msgs::Image>(
          "/" + c + "/camera/image_raw", 4,
          [this, c](const sensor_msgs::ImageConstPtr& m) { OnImage(c, m); }));
      subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          "/" + c + "/camera/camera_info", 4, [this, c](const sensor_msgs::CameraInfoConstPtr& m) {
            std::lock_guard<std::mutex> lock(cache_mutex_);
            infos_[c] = m;
          }));
    }
    subs_.push_back(nh.subscribe<slope_monitor::AdjustmentSolution>(
        "solution", 4,
        [this](const slope_monitor::AdjustmentSolutionConstPtr& m) { OnSolution(m); }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("dense_matcher");
    updater_->add("dense_matcher", this, &DenseEpochNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    worker_ = std::thread([this] { Work(); });
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    ros_adapters::DenseEpochParameters d = ros_adapters::ReadDenseEpochParameters(p);
    options_ = d.surface;
    change_options_ = d.change;
    outlines_ = std::move(d.outlines);
    stable_mask_path_ = d.stable_mask;
    cameras_ = d.cameras;
    uav_cameras_ = d.uav_cameras;
    stereo_pairs_ = d.stereo_pairs;
    pixel_size_ = d.pixel_size;
    max_cached_images_ = d.max_cached_images;
    frame_id_ = d.frame_id;
    report_dir_ = d.report_dir;
  }

  void OnImage(const std::string& camera, const sensor_msgs::ImageConstPtr& msg) {
    std::lock_guard<std::mutex> lock(cache_mutex_);
    auto& q = images_[camera];
    q.push_back(msg);
    while (static_cast<int>(q.size()) > max_cached_images_) q.pop_front();
  }

  void OnSolution(const slope_monitor::AdjustmentSolutionConstPtr& msg) {
    if (!msg->usable) {
      NODELET_WARN("dense_matcher: epoch %u not measured: the solution is not usable (%s)",
                   msg->epoch, msg->message.c_str());
      return;
    }
    Job job;
    job.header = msg->header;
    job.header.frame_id = frame_id_;
    job.input.epoch = static_cast<int>(msg->epoch);
    job.input.stereo_pairs = stereo_pairs_;
    job.input.adjusted_points = ros_adapters::AdjustedPoints(*msg);
    std::vector<std::string> missing;
    {
      std::lock_guard<std::mutex> lock(cache_mutex_);
      for (const slope_monitor::CameraEstimate& e : msg->cameras) {
        const auto info = infos_.find(e.camera_name);
        sensor_msgs::ImageConstPtr image;
        for (const auto& m : images_[e.camera_name])
          if (std::abs((m->header.stamp - e.image_header.stamp).toSec()) < 1e-3) image = m;
        if (!image || info == infos_.end()) {
          missing.push_back(Message(e.camera_name, "@", e.image_header.stamp.toSec()));
          continue;
        }
        const bool uav = std::find(uav_cameras_.begin(), uav_cameras_.end(), e.camera_name) !=
                         uav_cameras_.end();
        try {
          job.input.images.push_back(ros_adapters::EpochImageFromEstimate(
              e, *image, *info->second, pixel_size_,
              uav ? dense::ImageKind::kUav : dense::ImageKind::kFixed));
        } catch (const std::exception& ex) {
          missing.push_back(ex.what());
        }
      }
    }
    if (!missing.empty())
      NODELET_WARN("dense_matcher: epoch %u: %zu oriented image(s) not available (first: %s)",
                   msg->epoch, missing.size(), missing.front().c_str());
    const auto uav_images =
        std::count_if(job.input.images.begin(), job.input.images.end(),
                      [](const dense::EpochImage& i) { return i.kind == dense::ImageKind::kUav; });
    if (uav_images < 2 && stereo_pairs_.empty()) {
      // A survey without a UAV flight and without configured stereo pairs has
      // no surface to measure: not an error.
      NODELET_INFO("dense_matcher: epoch %u: no surface (fewer than two UAV photos, no stereo pair configured)",
                   msg->epoch);
      return;
    }
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      jobs_.push_back(std::move(job));
    }
    queue_cv_.notify_one();
  }

  void Work() {
    for (;;) {
      Job job;
      {
        std::unique_lock<std::mutex> lock(queue_mutex_);
        queue_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
        if (stop_) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      Process(job);
    }
  }

  std::string ReportPath(const std::string& name) const {
    std::filesystem::create_directories(report_dir_);
    return report_dir_ + "/" + name;
  }

  void Process(const Job& job) {
    const int epoch = job.input.epoch;
    dense::EpochSurfaceResult surface;
    try {
      dense::EpochSurfaceOptions o = options_;
      if (reference_) o.region = dense::RegionOf(*reference_);
      surface = dense::MeasureEpochSurface(job.input, o, [this](const std::string& step) {
        NODELET_INFO("dense_matcher: %s", step.c_str());
      });
      NODELET_INFO("dense_matcher: %s", surface.summary.BriefReport().c_str());
      if (!report_dir_.empty())
        io::WriteGeoTiff(ReportPath(dense::EpochSurfaceFileName(epoch)), surface.dem);
    } catch (const std::exception& e) {
      Fail(Message("epoch ", epoch, " surface: ", e.what()));
      return;
    }
    std::unique_ptr<dense::DemChangeResult> change;
    if (!reference_) {
      reference_ = std::make_unique<io::GeoRaster>(surface.dem);
      reference_epoch_ = epoch;
    } else {
      try {
        std::vector<uint8_t> mask;
        if (!stable_mask_path_.empty()) {
          const io::GeoRaster m = io::ReadGeoTiff(stable_mask_path_);
          for (float v : m.bands.at(0)) mask.push_back(!m.IsNoData(v) && v != 0.0f);
        }
        const std::vector<uint8_t> stable =
            dense::StableMask(*reference_, outlines_, mask, stable_mask_path_);
        change = std::make_unique<dense::DemChangeResult>(
            dense::DemChange(*reference_, surface.dem, outlines_, stable, change_options_));
        NODELET_INFO("dense_matcher: epoch %d change: %s", epoch,
                     change->summary.BriefReport().c_str());
        if (!report_dir_.empty())
          io::WriteGeoTiff(ReportPath(dense::EpochChangeFileName(epoch)), change->change);
      } catch (const std::exception& e) {
        Fail(Message("epoch ", epoch, " change (the surface is kept): ", e.what()));
        change.reset();
      }
    }
    cloud_pub_.publish(ros_adapters::MakeSurfaceCloud(surface, change.get(), job.header));
    if (change) PublishAreas(change->change, epoch, job.header);
    std::lock_guard<std::mutex> lock(state_mutex_);
    ++epochs_;
    last_summary_ = surface.summary.BriefReport();
    last_change_ = change ? change->summary.BriefReport() : "";
  }

  // The polygons of significant change (core/dense/change_polygons.h) to the
  // deformation estimator, as an area measurement (source surface).
  void PublishAreas(const io::GeoRaster& dod, int epoch, const std_msgs::Header& header) {
    try {
      const std::vector<dense::ChangePolygon> polygons =
          dense::ChangePolygons(dod, dense::ChangePolygonOptions());
      NODELET_INFO("dense_matcher: epoch %d: %zu area(s) of significant change", epoch,
                   polygons.size());
      areas_pub_.publish(ros_adapters::ToChangeAreaMsg(
          polygons, static_cast<uint32_t>(epoch), static_cast<uint32_t>(reference_epoch_), header));
    } catch (const std::exception& e) {
      Fail(Message("epoch ", epoch, " change polygons (the DoD is kept): ", e.what()));
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
    stat.add("last surface", last_summary_);
    stat.add("last change", last_change_);
    stat.add("last error", last_error_);
  }

  dense::EpochSurfaceOptions options_;
  dense::DemChangeOptions change_options_;
  std::vector<dense::Polygon> outlines_;
  std::string stable_mask_path_;
  std::vector<std::string> cameras_, uav_cameras_;
  std::vector<std::pair<std::string, std::string>> stereo_pairs_;
  double pixel_size_ = 0.0;
  int max_cached_images_ = 0;
  std::string frame_id_;
  std::string report_dir_;
  ros::Publisher cloud_pub_, areas_pub_;
  std::vector<ros::Subscriber> subs_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  std::mutex cache_mutex_;  // images_, infos_
  std::map<std::string, std::deque<sensor_msgs::ImageConstPtr>> images_;
  std::map<std::string, sensor_msgs::CameraInfoConstPtr> infos_;
  std::mutex queue_mutex_;  // jobs_, stop_
  std::condition_variable queue_cv_;
  std::deque<Job> jobs_;
  bool stop_ = false;
  std::thread worker_;
  std::unique_ptr<io::GeoRaster> reference_;  // worker thread only
  int reference_epoch_ = 0;                   // worker thread only
  std::mutex state_mutex_;                    // counters and reports
  int epochs_ = 0, failures_ = 0;
  std::string last_summary_, last_change_, last_error_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DenseEpochNodelet, nodelet::Nodelet)
