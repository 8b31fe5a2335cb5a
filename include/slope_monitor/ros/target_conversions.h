// One image through the target centroider (core/targets): the checks, the
// view geometry from camera_info and the camera's pose in `site`, detection,
// and the TargetObservationArray the target_centroider nodelet publishes.
// Shared by the nodelet and the process_bag tool.
#pragma once

#include <optional>
#include <string>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <Eigen/Geometry>

#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace ros_adapters {

// TargetObservation::ROLE_* of a listed target's role (nullopt: not listed).
uint8_t TargetRoleToMsg(const std::optional<io::TargetRole>& role);

struct CentroidedImage {
  slope_monitor::TargetObservationArray targets;
  targets::Result result;
  targets::MonoImage mono;  // for the debug image; may share the input image's pixels
};

// `site_from_optical`: the camera's pose (tf), or nothing (circles stay
// unidentified, no perspective correction); used only with a calibrated
// camera_info (K[0] > 0). `topic` names the input in error messages. Throws
// slope_monitor::Error (bad input), cv_bridge::Exception or cv::Exception.
CentroidedImage CentroidImage(const targets::TargetCentroider& centroider,
                              const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info,
                              const std::optional<Eigen::Isometry3d>& site_from_optical,
                              const std::string& camera_name, double pixel_size,
                              const std::string& topic);

// The debug image of `c` (targets::DrawResult: detected targets drawn, bgr8)
// with `header` (the input image's): what the centroider's `debug_image` shows.
sensor_msgs::Image ToDebugImage(const CentroidedImage& c, const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
