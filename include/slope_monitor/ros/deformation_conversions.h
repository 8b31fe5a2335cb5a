// Conversions between the deformation core (core/deformation/estimator.h)
// and ROS messages: displacements in, deformation / markers / cloud / alerts out.
#pragma once

#include <string>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/SlopeDeformation.h"
#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace ros_adapters {

// One batch per message; measurement stamps of zero take the header stamp.
// Throws InvalidArgument naming the topic for an unknown source code.
deformation::Batch FromMsg(const slope_monitor::PointDisplacementArray& msg,
                           const std::string& topic);

slope_monitor::SlopeDeformation ToMsg(const deformation::Snapshot& snapshot,
                                      const std_msgs::Header& header);

// One point's displacement as a source publishes it (significance left 0 for
// the caller): positions and displacement [m] in site, covariance [m^2].
slope_monitor::PointDisplacement MakePointDisplacement(
    const std::string& point_id, uint8_t source, const std::string& source_name,
    double reference_stamp, const ros::Time& stamp, const Eigen::Vector3d& reference_position,
    const Eigen::Vector3d& displacement, const Eigen::Matrix3d& covariance);

// Sized to read at site scale (a 100-200 m slope seen whole in rviz): a
// 0.3 m displacement is a 15 m arrow, labels 2.5 m high.
struct MarkerOptions {
  double arrow_scale = 50.0;  // [m of arrow per m of displacement]
  double text_size = 2.5;     // [m]
  double point_size = 1.5;    // [m]
};
// Per point: a sphere at the reference position, an arrow along the
// displacement (scaled), a text label "id |d| mm v mm/day ALERT"; colour by
// alert level (green, yellow, orange, red). Namespaces "points", "arrows",
// "labels"; a DELETEALL first so vanished points disappear.
visualization_msgs::MarkerArray ToMarkers(const deformation::Snapshot& snapshot,
                                          const std_msgs::Header& header,
                                          const MarkerOptions& options);

// x y z (reference position, float32), displacement [m] (float32) and rgb
// (packed float, blue -> red over 0 .. max displacement).
sensor_msgs::PointCloud2 ToCloud(const deformation::Snapshot& snapshot,
                                 const std_msgs::Header& header);

// One DiagnosticStatus per point ("deformation/<id>", level OK for none,
// WARN for watch and warning, ERROR for alarm) and one for the slope.
diagnostic_msgs::DiagnosticArray ToAlerts(const deformation::Snapshot& snapshot,
                                          const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
