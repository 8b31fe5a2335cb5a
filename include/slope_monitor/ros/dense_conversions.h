// Conversions for the epoch surface (core/dense/epoch_surface.h,
// core/dense/dem_change.h): the adjuster's CameraEstimate + the image and its
// camera_info -> dense::EpochImage, and an epoch's surface -> PointCloud2.
#pragma once

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_photos.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {

// The keys of config/defaults/dense_epoch.yaml, read once for the dense
// matcher node (parameter server) and for `dense_surface --bag` (the same
// file, ros/param_files.h). Defaults: the core Options' own. Throws
// ConfigError naming the key (CheckNoUnknownKeys is called).
struct DenseEpochParameters {
  dense::EpochSurfaceOptions surface;
  dense::DemChangeOptions change;
  std::vector<dense::Polygon> outlines;  // monitored_outline (site)
  std::string stable_mask;               // GeoTIFF, "" = none
  std::vector<std::string> cameras, uav_cameras;
  std::vector<std::pair<std::string, std::string>> stereo_pairs;
  double pixel_size = 0.0;  // [mm/px]
  // uav_cameras, stereo_pairs as above; max_cached_images, max_cached_megabytes, photo_wait.
  dense::PhotoCollectorOptions photos;
  std::string frame_id, report_dir;
  // change_colour_min / max: the colour scale of `change` (the legend; rviz's
  // cloud display is set to the same numbers).
  ChangeScaleOptions change_scale;
};
DenseEpochParameters ReadDenseEpochParameters(ParamReader& p);

// The image with the ADJUSTED orientation and interior orientation of
// `estimate` (sensor size and distortion model from `info`). Throws
// InvalidArgument naming the camera when the distortion vector is too long.
dense::EpochImage EpochImageFromEstimate(const slope_monitor::CameraEstimate& estimate,
                                         const sensor_msgs::Image& image,
                                         const sensor_msgs::CameraInfo& info, double pixel_size,
                                         dense::ImageKind kind);

// The adjusted points of a solution [m, site].
std::vector<Eigen::Vector3d> AdjustedPoints(const slope_monitor::AdjustmentSolution& solution);

// Cloud in header.frame_id with fields x y z rgb sigma_z change lod (FLOAT32;
// rgb packed as PCL does). change / lod: the DoD cell of the point, NaN when
// there is no change (reference epoch, or the cell is a hole).
sensor_msgs::PointCloud2 MakeSurfaceCloud(const dense::EpochSurfaceResult& surface,
                                          const dense::DemChangeResult* change,
                                          const std_msgs::Header& header);

// The colour scale of `change` (view_markers.h) standing beside the surface:
// at the east edge of the points' extent plus 5 % of its larger side, at the
// middle of its north extent, from the lowest point up, half as tall as the
// larger side. Empty surface: an empty array.
visualization_msgs::MarkerArray MakeChangeScaleBeside(const dense::EpochSurfaceResult& surface,
                                                      const ChangeScaleOptions& options,
                                                      const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
