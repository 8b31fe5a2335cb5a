// Conversions for the epoch surface (core/dense/epoch_surface.h,
// core/dense/dem_change.h): the adjuster's CameraEstimate + the image and its
// camera_info -> dense::EpochImage, and an epoch's surface -> PointCloud2.
#pragma once

#include <optional>

#include <geometry_msgs/TransformStamped.h>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/dense/change.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_photos.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/dense/surface_products.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {

// The graph's dense surfaces, where they differ from the library's
// dense::SurfaceOptions: a 2 px final grid (0.2 m on the ground from 25-45 m:
// several points per 0.5 m cell) and no cell from a single point. Both dense
// nodes (stereo and epoch) start from these. The library keeps doc/design.md's
// 8 px grid (correlation.h) for its own callers and tests. Measured with
// process_bag on dense_graph_replay (replay_process_bag_dense_test), 2 vs
// 8 px: cloud 635 k / 1.13 M vs 40 k / 71 k points per epoch, DEM cells on
// bare ground 8903 / 9760 vs 8398 / 9363, median |e| 0.073 / 0.031 vs
// 0.072 / 0.034 m, p90 0.174 / 0.102 vs 0.165 / 0.100 m; test wall time 53
// vs 42 s: the same heights, 16 x the points and 5 % more cells.
inline void ApplyGraphSurfaceDefaults(dense::SurfaceOptions* o) {
  o->correlation.final_grid_spacing = 2;
  o->min_points_per_cell = 2;
}
inline dense::SurfaceOptions StereoSurfaceOptions() {
  dense::SurfaceOptions o;
  ApplyGraphSurfaceDefaults(&o);
  return o;
}
inline dense::EpochSurfaceOptions GraphEpochSurfaceOptions() {
  dense::EpochSurfaceOptions o;
  ApplyGraphSurfaceDefaults(&o.surface);
  return o;
}

// The keys of config/defaults/dense_epoch.yaml, read once for the dense
// matcher node (parameter server) and for `dense_surface --bag` (the same
// file, ros/param_files.h). Defaults: the core Options' own. Throws
// ConfigError naming the key (CheckNoUnknownKeys is called).
struct DenseEpochParameters {
  dense::EpochSurfaceOptions surface = GraphEpochSurfaceOptions();
  dense::SurfaceChangeOptions change;     // co-registration (shift search, Nuth-Kaab) and DoD
  std::vector<double> monitored_outline;  // [x1, y1, x2, y2, ...] (m, site) as written
  std::vector<dense::Polygon> outlines;   // monitored_outline (site)
  std::string stable_mask;                // GeoTIFF, "" = none
  std::vector<std::string> cameras, uav_cameras;
  std::vector<std::pair<std::string, std::string>> stereo_pairs;
  std::string
      site_file;  // its cameras and their kinds, when it lists them ("" = cameras, uav_cameras)
  std::string site_config;  // estimator overlay: its geodetic_origin when no site file is given
  // The GeoTIFFs' map CRS: the site file's CRS, else local ENU at site_config's
  // geodetic_origin, else none (local CRS `site`).
  std::optional<SiteCrsOptions> site_crs;
  double pixel_size =
      0.0048;  // [mm/px] of a camera the site file does not give (the simulator's cameras)
  // uav_cameras, stereo_pairs as above; max_cached_images, max_cached_megabytes, photo_wait.
  dense::PhotoCollectorOptions photos;
  std::string frame_id = "site", report_dir;
  // change_colour_min / max: the colour scale of `change` (the legend; rviz's
  // cloud display is set to the same numbers).
  ChangeScaleOptions change_scale;
};
DenseEpochParameters ReadDenseEpochParameters(ParamReader& p);

// The estimator overlay's geodetic_origin [lat, lon, h] as a local ENU site
// (the GeoTIFFs' map CRS when no site file gives one, as the reports'
// deformation::ReportSiteCrs); none when the file has no geodetic_origin.
// Throws ConfigError naming the file for a list that is not 3 numbers.
std::optional<SiteCrsOptions> SiteCrsOfOverlay(const std::string& site_config);

// The stereo dense matcher's keys (config/defaults/dense_matcher.yaml), read
// once for the dense_matcher nodelet (parameter server) and for the
// dense_surface tool (--config, the same file). The in-class values are the
// defaults; where the node's differ from the library's, StereoSurfaceOptions
// says why.
struct DenseMatcherParameters {
  dense::SurfaceOptions surface = StereoSurfaceOptions();
  dense::SurfaceConfig config = {5.0, 500.0};  // [m] min_depth, max_depth; region: bounding box
  dense::ChangeOptions change;
  double pixel_size = 0.00345;  // [mm/px] to read camera_info into the camera model
  double max_pair_dt = 1.0;     // [s] left and right stamps may differ by this much
  std::string frame_id = "site";
  std::string output_dir;   // GeoTIFFs written here ("" = none)
  double tf_timeout = 0.5;  // [s] wait for the camera transform
  std::string site_file;    // its crs: the GeoTIFFs' map CRS ("" = none)
  std::string site_config;  // estimator overlay: its geodetic_origin when no site file is given
  // The GeoTIFFs' map CRS (as DenseEpochParameters::site_crs): the site file's
  // CRS, else local ENU at site_config's geodetic_origin, else none (local CRS `site`).
  std::optional<SiteCrsOptions> site_crs;
};
DenseMatcherParameters ReadDenseMatcherParameters(ParamReader& p);

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

// ---- the dense_matcher node (a stereo pair, core/dense/surface.h).

// An image of a pair with its camera (from `info`, pixel_size [mm]), not
// yet oriented. Throws InvalidArgument when the image message is beyond the
// pixel budget or does not describe its data (ros/image_limits.h).
dense::OrientedImage PairImage(const sensor_msgs::Image::ConstPtr& image,
                               const sensor_msgs::CameraInfo& info, double pixel_size);

// `image` oriented by the transform site <- <camera>_optical at its stamp.
void OrientPairImage(const geometry_msgs::TransformStamped& site_from_optical,
                     dense::OrientedImage* image);

// The measured points: fields x y z intensity sigma_z (FLOAT32), in header.frame_id.
sensor_msgs::PointCloud2 PairSurfaceCloud(const dense::SurfaceResult& s,
                                          const std_msgs::Header& header);

// The significant change against the reference: fields x y z dz lod (FLOAT32).
sensor_msgs::PointCloud2 PairChangeCloud(const dense::ChangeResult& c,
                                         const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
