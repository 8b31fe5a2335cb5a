// dense_matcher: dense surface measurement of an oriented image pair
// (core/dense/surface.h) and its change between epochs (core/dense/change.h).
//
// Thin wrapper: parameters -> SurfaceOptions; left/right images + camera_info
// + tf (site -> <camera>_optical at the image stamp) -> OrientedImage
// (ros/dense_conversions.h, as the clouds); the core does the rest.
// Outputs: the measured points (PointCloud2 in `site`, fields x y z
// intensity sigma_z), the significant change against the reference epoch
// (PointCloud2, fields x y z dz lod), and, when output_dir is set, GeoTIFFs
// of the surface model, orthophoto and change per pair: in the site's map
// CRS (an EPSG code, io::MapRasterFromSite) when site_file (its crs) or
// site_config (its geodetic_origin) georeferences them, else in the
// local CRS `site` (said in the log at start).
//
// A pair is formed from the latest left and right image whose stamps differ
// by at most max_pair_dt; each image is used once. Subscriptions are not lazy:
// the reference surface must be measured whether or not anyone listens.
#include <iomanip>
#include <memory>
#include <mutex>
#include <sstream>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/change.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class DenseMatcherNodelet : public nodelet::Nodelet {
 private:
  struct Side {
    sensor_msgs::ImageConstPtr image;
    sensor_msgs::CameraInfoConstPtr info;
  };

  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      NODELET_ERROR("dense_matcher: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "dense_matcher", "parameters rejected: " + *error);
      return;
    }
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(3600.0));
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh);
    surface_pub_ = nh.advertise<sensor_msgs::PointCloud2>("surface", 2, true);
    change_pub_ = nh.advertise<sensor_msgs::PointCloud2>("surface_change", 2, true);
    subs_.push_back(nh.subscribe<sensor_msgs::Image>(
        "left/image", 2, [this](const sensor_msgs::ImageConstPtr& m) { OnImage(0, m); }));
    subs_.push_back(nh.subscribe<sensor_msgs::Image>(
        "right/image", 2, [this](const sensor_msgs::ImageConstPtr& m) { OnImage(1, m); }));
    subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
        "left/camera_info", 2, [this](const sensor_msgs::CameraInfoConstPtr& m) { OnInfo(0, m); }));
    subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
        "right/camera_info", 2,
        [this](const sensor_msgs::CameraInfoConstPtr& m) { OnInfo(1, m); }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("dense_matcher");
    updater_->add("dense_matcher", this, &DenseMatcherNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    const ros_adapters::DenseMatcherParameters d = ros_adapters::ReadDenseMatcherParameters(p);
    options_ = d.surface;
    config_ = d.config;
    change_options_ = d.change;
    pixel_size_ = d.pixel_size;
    max_pair_dt_ = d.max_pair_dt;
    frame_id_ = d.frame_id;
    output_dir_ = d.output_dir;
    tf_timeout_ = d.tf_timeout;
    if (d.site_crs) site_ = std::make_unique<SiteCrs>(*d.site_crs);
    if (output_dir_.empty()) return;
    if (site_)
      NODELET_INFO("dense_matcher: GeoTIFFs in %s (the site's map CRS, from %s)",
                   site_->MapCrs().c_str(),
                   d.site_file.empty() ? ("site_config " + d.site_config).c_str()
                                       : ("site_file " + d.site_file).c_str());
    else
      NODELET_INFO(
          "dense_matcher: GeoTIFFs in the local CRS 'site' (no EPSG code): neither site_file "
          "nor site_config's geodetic_origin georeferences them");
  }

  void OnInfo(int side, const sensor_msgs::CameraInfoConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sides_[side].info = msg;
  }

  void OnImage(int side, const sensor_msgs::ImageConstPtr& msg) {
    std::unique_lock<std::mutex> lock(mutex_);
    sides_[side].image = msg;
    if (!sides_[0].image || !sides_[1].image) return;
    if (std::abs((sides_[0].image->header.stamp - sides_[1].image->header.stamp).toSec()) >
        max_pair_dt_)
      return;
    const Side left = sides_[0], right = sides_[1];
    sides_[0].image.reset();
    sides_[1].image.reset();
    lock.unlock();
    try {
      Process(left, right);
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> state(state_mutex_);
      ++failed_pairs_;
      last_error_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "dense_matcher: pair at %.3f dropped: %s",
                             left.image->header.stamp.toSec(), e.what());
    }
  }

  dense::OrientedImage ToOriented(const Side& s, const char* role) {
    if (!s.info)
      throw InvalidArgument(Message("no camera_info received yet on ", role, "/camera_info"));
    dense::OrientedImage im = ros_adapters::PairImage(s.image, *s.info, pixel_size_);
    geometry_msgs::TransformStamped t;
    try {
      t = tf_buffer_->lookupTransform(frame_id_, s.image->header.frame_id, s.image->header.stamp,
                                      ros::Duration(tf_timeout_));
    } catch (const tf2::TransformException& e) {
      throw InvalidArgument(Message(role, " image '", s.image->header.frame_id,
                                    "' is not oriented: no transform ", frame_id_, " <- ",
                                    s.image->header.frame_id, " (", e.what(), ")"));
    }
    ros_adapters::OrientPairImage(t, &im);
    return im;
  }

  void Process(const Side& l, const Side& r) {
    const dense::OrientedImage left = ToOriented(l, "left"), right = ToOriented(r, "right");
    dense::SurfaceSummary summary;
    std::ostringstream stem;
    stem << output_dir_ << "/dense_" << std::fixed << std::setprecision(3)
         << l.image->header.stamp.toSec();
    // With output_dir: surface and orthophoto written only after a successful
    // measurement (temporary names, renamed), never a half set.
    const dense::SurfaceResult s =
        output_dir_.empty() ? dense::MeasureSurface(left, right, options_, config_, &summary)
                            : dense::MeasureSurfaceToFiles(left, right, options_, config_,
                                                           stem.str(), &summary, site_.get());
    std_msgs::Header header = l.image->header;
    header.frame_id = frame_id_;
    surface_pub_.publish(ros_adapters::PairSurfaceCloud(s, header));
    {
      std::lock_guard<std::mutex> state(state_mutex_);
      ++pairs_;
      last_summary_ = summary.BriefReport();
    }
    NODELET_INFO("dense_matcher: %s", summary.BriefReport().c_str());
    std::unique_lock<std::mutex> state(state_mutex_);
    if (!reference_) {
      // The first measured pair is the reference epoch of the change.
      reference_ = std::make_unique<io::GeoRaster>(s.model);
      return;
    }
    const dense::ChangeResult c = dense::SurfaceChange(*reference_, s.model, change_options_);
    last_change_ = c.summary.BriefReport();
    state.unlock();
    NODELET_INFO("dense_matcher: %s", c.summary.BriefReport().c_str());
    change_pub_.publish(ros_adapters::PairChangeCloud(c, header));
    if (!output_dir_.empty())
      io::WriteGeoTiff(stem.str() + "_change.tif", io::MapRasterFromSite(c.change, site_.get()));
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (failed_pairs_ > 0 && pairs_ == 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                   "no pair measured; last error: " + last_error_);
    } else if (pairs_ == 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "waiting for an image pair");
    } else {
      stat.summary(failed_pairs_ > 0 ? diagnostic_msgs::DiagnosticStatus::WARN
                                     : diagnostic_msgs::DiagnosticStatus::OK,
                   "measuring");
    }
    stat.add("pairs measured", pairs_);
    stat.add("pairs dropped", failed_pairs_);
    stat.add("last surface", last_summary_);
    stat.add("last change", last_change_);
    stat.add("last error", last_error_);
    stat.add("reference surface", reference_ ? "set" : "not yet");
  }

  dense::SurfaceOptions options_;
  dense::SurfaceConfig config_;
  dense::ChangeOptions change_options_;
  double pixel_size_ = 0.0;  // the members below: ros_adapters::DenseMatcherParameters
  double max_pair_dt_ = 0.0;
  double tf_timeout_ = 0.0;
  std::string frame_id_;
  std::string output_dir_;
  std::unique_ptr<SiteCrs> site_;  // the GeoTIFFs' map CRS (none: local CRS `site`)
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Publisher surface_pub_, change_pub_;
  std::vector<ros::Subscriber> subs_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  std::mutex mutex_;        // the pending images
  std::mutex state_mutex_;  // counters, reports, reference surface
  Side sides_[2];
  std::unique_ptr<io::GeoRaster> reference_;
  int pairs_ = 0;
  int failed_pairs_ = 0;
  std::string last_summary_, last_change_, last_error_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::DenseMatcherNodelet, nodelet::Nodelet)
