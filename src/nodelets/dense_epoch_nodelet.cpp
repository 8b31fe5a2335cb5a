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
// and, with report_dir, surface_eNN.tif and change_eNN.tif there. The first
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
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/io/geotiff.h"
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
    dense::SurfaceOptions& s = options_.surface;
    dense::CorrelationOptions& c = s.correlation;
    c.levels = p.Int("levels", c.levels, 1, 5);
    c.peak_frequency = p.Double("peak_frequency", c.peak_frequency, 0.01, 3.0, "rad/px");
    c.grid_spacing = p.Int("grid_spacing", c.grid_spacing, 1, 64, "px");
    c.final_grid_spacing = p.Int("final_grid_spacing", c.final_grid_spacing, 1, 64, "px");
    c.window = p.Int("window", c.window, 3, 51, "px");
    c.final_window = p.Int("final_window", c.final_window, 0, 51, "px");
    c.lsc_iterations = p.Int("lsc_iterations", c.lsc_iterations, 0, 20);
    c.search_radius = p.Int("search_radius", c.search_radius, 1, 16, "px");
    c.min_correlation = p.Double("min_correlation", c.min_correlation, -1.0, 0.999);
    s.rectify.scale = p.Double("rectify_scale", s.rectify.scale, 0.05, 4.0);
    s.rectify.patch_size = p.Int("patch_size", s.rectify.patch_size, 0, 8192, "px");
    s.cell_size = p.Double("cell_size", s.cell_size, 1e-3, 100.0, "m");
    s.min_points_per_cell = p.Int("min_points_per_cell", s.min_points_per_cell, 1, 1000);
    s.parallax_sigma = p.Double("parallax_sigma", s.parallax_sigma, 1e-3, 10.0, "px");
    options_.min_pair_overlap = p.Double("min_pair_overlap", options_.min_pair_overlap, 0.01, 1.0);
    options_.depth_margin = p.Double("depth_margin", options_.depth_margin, 0.0, 10.0);
    options_.max_pairs_per_image =
        p.Int("max_pairs_per_image", options_.max_pairs_per_image, 1, 100);
    options_.max_dem_megabytes =
        p.Double("max_dem_megabytes", options_.max_dem_megabytes, 1e-3, 1e5, "MB");
    const std::vector<double> region = p.DoubleList("region", {0.0, 0.0, 0.0, 0.0});
    if (region.size() != 4)
      throw ConfigError(
          Message("parameter '", p.FullKey("region"), "' must be [xmin, xmax, ymin, ymax] (m)"));
    options_.region = Eigen::Vector4d(region[0], region[1], region[2], region[3]);
    change_options_.lod_factor = p.Double("lod_factor", change_options_.lod_factor, 0.01, 10.0);
    change_options_.coregistration_iterations =
        p.Int("coregistration_iterations", change_options_.coregistration_iterations, 0, 20);
    change_options_.min_stable_cells =
        p.Int("min_stable_cells", change_options_.min_stable_cells, 4, 1000000000);
    const std::vector<double> outline = p.DoubleList("monitored_outline", {});
    if (outline.size() % 2 != 0 || (!outline.empty() && outline.size() < 6))
      throw ConfigError(
          Message("parameter '", p.FullKey("monitored_outline"),
                  "' must be [x1, y1, x2, y2, x3, y3, ...] (m, site; at least 3 vertices)"));
    if (!outline.empty()) {
      outlines_.emplace_back();
      for (size_t i = 0; i < outline.size(); i += 2)
        outlines_.back().emplace_back(outline[i], outline[i + 1]);
    }
    stable_mask_path_ = p.String("stable_mask", "");
    cameras_ = p.StringList("cameras", {"fixed_cam_1", "fixed_cam_2", "uav"});
    uav_cameras_ = p.StringList("uav_cameras", {"uav"});
    const std::vector<std::string> pairs = p.StringList("stereo_pairs", {});
    if (pairs.size() % 2 != 0)
      throw ConfigError(Message("parameter '", p.FullKey("stereo_pairs"),
                                "' must list cameras in pairs (left, right)"));
    for (size_t i = 0; i < pairs.size(); i += 2) stereo_pairs_.push_back({pairs[i], pairs[i + 1]});
    pixel_size_ = p.Double("pixel_size", 0.0048, 1e-6, 1.0, "mm/px");
    max_cached_images_ = p.Int("max_cached_images", 64, 1, 10000);
    frame_id_ = p.String("frame_id", "site");
    report_dir_ = p.String("report_dir", "");
    p.CheckNoUnknownKeys();
    options_.Check();
    change_options_.Check();
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
    std::lock_guard<std::mutex> lock(state_mutex_);
    ++epochs_;
    last_summary_ = surface.summary.BriefReport();
    last_change_ = change ? change->summary.BriefReport() : "";
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
  double pixel_size_ = 0.0048;
  int max_cached_images_ = 64;
  std::string frame_id_ = "site";
  std::string report_dir_;
  ros::Publisher cloud_pub_;
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
  std::mutex state_mutex_;                    // counters and reports
  int epochs_ = 0, failures_ = 0;
  std::string last_summary_, last_change_, last_error_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DenseEpochNodelet, nodelet::Nodelet)
