// The dense epoch step of the graph, from ROS messages: photos and
// camera_info of the surface cameras are collected by message
// (dense::EpochPhotoCollector), each usable AdjustmentSolution names the
// photos it oriented, and a complete epoch is measured into one surface and
// its change against the reference epoch, co-registered on stable ground
// (dense::SurfaceSeries, with report_dir also the files process_flight
// writes per flight), giving a PointCloud2 in frame_id with fields x y z rgb
// sigma_z change lod. The
// dense_epoch nodelet (its worker thread measures, its callbacks collect) and
// process_bag (in bag-time order, in one thread) use this same class.
// Not thread-safe: Measure() may run on another thread than the On*() calls
// (it touches only the series), but each group on one thread at a time.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/ChangeAreaArray.h"
#include "slope_monitor/core/dense/epoch_photos.h"
#include "slope_monitor/core/dense/surface_series.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/epoch_solver.h"

namespace slope_monitor {
namespace ros_adapters {

// The series' options from the node's parameters (surface, change,
// outlines, stable_mask, report_dir).
dense::SurfaceSeriesOptions SeriesOptions(const DenseEpochParameters& parameters);

// A usable solution's orientations for the photo collector.
dense::EpochOrientations OrientationsOf(const slope_monitor::AdjustmentSolution& solution);

struct DenseEpochOutput {
  int epoch = 0;
  std::optional<sensor_msgs::PointCloud2> cloud;  // none: no surface
  // With the cloud: the colour scale of its `change` beside it (change_legend).
  std::optional<visualization_msgs::MarkerArray> legend;
  std::vector<std::string> files;  // GeoTIFFs written
  std::vector<LogLine> log;        // what happened, named
  // Later epochs: the polygons of significant change of the DoD
  // (core/dense/change_polygons.h), for the deformation estimator.
  std::optional<slope_monitor::ChangeAreaArray> areas;
};

class DenseEpochStep {
 public:
  explicit DenseEpochStep(const DenseEpochParameters& parameters);  // ConfigError

  // ---- collection (cheap). `now` [s]: the caller's clock (bag or ROS time).
  bool Uses(const std::string& camera) const { return photos_.Uses(camera); }
  // Throws Error naming the camera for a camera_info that cannot be read.
  void OnCameraInfo(const std::string& camera, const sensor_msgs::CameraInfo& info);
  std::vector<dense::PhotoEpoch> OnImage(const std::string& camera, const sensor_msgs::Image& image,
                                         double now);
  // An unusable solution gives no epoch (a log line says why).
  std::vector<dense::PhotoEpoch> OnSolution(const slope_monitor::AdjustmentSolution& solution,
                                            double now);
  std::vector<dense::PhotoEpoch> Poll(double now) { return photos_.Poll(now); }
  std::vector<dense::PhotoEpoch> Finish() { return photos_.Finish(); }
  // Lines about the collection (photos dropped at the limit, unusable solutions).
  std::vector<LogLine> TakeLog();
  const dense::EpochPhotoCollector& photos() const { return photos_; }

  // ---- measurement (seconds per epoch).
  DenseEpochOutput Measure(const dense::PhotoEpoch& epoch,
                           const std::function<void(const std::string&)>& progress = {});

 private:
  DenseEpochParameters parameters_;
  dense::EpochPhotoCollector photos_;
  dense::SurfaceSeries series_;
  int reference_epoch_ = -1;  // the first epoch measured
  std::vector<LogLine> log_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
