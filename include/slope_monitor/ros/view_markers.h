// rviz markers a crew reads the slope with, made from
// what the nodes already compute: the camera frustums of an adjusted epoch
// (bundle_adjuster `frustums`) and the colour scale of the dense surface's
// `change` field (dense_matcher `change_legend`). Conversion only: the
// geometry is the collinearity model's (doc/design.md) read backwards.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <std_msgs/ColorRGBA.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>
#include <Eigen/Core>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace ros_adapters {

struct FrustumOptions {
  double depth = 12.0;       // apex to image plane, along the optical axis [m]
  double line_width = 0.25;  // [m]
  // The UAV cameras (kind uav of the site file, or of io::DefaultCameras()).
  std::vector<std::string> uav_cameras = adjustment::DefaultUavCameras();
  void Check() const;  // ConfigError naming the bad value
};

// One LINE_LIST pyramid per camera of `solution` (namespace "frustums", id =
// index in solution.cameras), after a DELETEALL: 4 edges from the apex (the
// adjusted projection centre) to the image corners and the 4 sides of the
// image rectangle, the corners being the sensor's corners (sensor of
// models[camera_name], principal distance and principal point adjusted)
// projected to `depth` along the optical axis (distortion not applied). A
// camera with no model in `models` gets no pyramid. Fixed cameras green, UAV
// photos (options.uav_cameras) orange. Header: the solution's.
visualization_msgs::MarkerArray ToFrustumMarkers(
    const slope_monitor::AdjustmentSolution& solution,
    const std::map<std::string, camera::CameraModel>& models, const FrustumOptions& options);

// The image corners in the optical frame (REP 103: x right, y down, z
// forward) at `depth`, in the order top-left, top-right, bottom-right,
// bottom-left as seen in the image: x = depth (x_mm - x0) / c,
// y = -depth (y_mm - y0) / c, z = depth with x_mm = -+W/2, y_mm = +-H/2 the
// sensor's half size [mm].
std::array<Eigen::Vector3d, 4> FrustumCornersInOptical(const camera::Sensor& sensor,
                                                       double principal_distance, double x0,
                                                       double y0, double depth);

struct ChangeScaleOptions {
  // The `change` value shown in the first / last colour [m]; rviz's cloud
  // display uses the same numbers (rviz/slope_monitor.rviz, Min/Max Intensity).
  double min = -1.0;
  double max = 1.0;
  int steps = 10;      // coloured cubes [-]
  int labels = 5;      // labelled values, min and max included [-]
  void Check() const;  // ConfigError naming the bad value
};

// rviz's rainbow for an intensity channel with "Invert Rainbow" on, for
// t = (value - min) / (max - min) clamped to [0, 1]: magenta (0), blue,
// cyan, green, yellow, red (1).
std_msgs::ColorRGBA RvizRainbow(double t);

// The colour scale as a vertical bar of `steps` CUBEs (namespace
// "change_scale", colour of each cube's middle value) standing at
// `base_in_frame` (bottom of the bar), `height` [m] tall, with
// TEXT_VIEW_FACING labels "-1.0 m" ... "+1.0 m" (namespace
// "change_scale_labels", `labels` values evenly from min to max, beside the
// bar) and a title "change [m]" above it. A DELETEALL first.
visualization_msgs::MarkerArray ToChangeScaleMarkers(const ChangeScaleOptions& options,
                                                     const Eigen::Vector3d& base_in_frame,
                                                     double height, const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
