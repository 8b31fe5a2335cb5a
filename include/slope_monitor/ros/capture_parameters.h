// The camera_capture node's keys (config/defaults/camera_capture.yaml), read
// once into typed options. The in-class values are the defaults a node gets
// when neither the yaml nor the launch sets a key (test/ros/config_files_test
// checks the yaml against them). Throws ConfigError naming the key.
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/ros/capture_conversions.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {

// The node's schedule: a fixed camera captures every 10 minutes unless told
// otherwise (the library's ScheduleOptions default is trigger only).
inline capture::ScheduleOptions NodeScheduleOptions() {
  capture::ScheduleOptions s;
  s.interval = 600.0;
  return s;
}

struct CaptureParameters {
  std::string source = "device";  // device | folder | video
  std::string camera_name =
      "camera";           // camera_info_manager's name; frame_id defaults to <camera_name>_optical
  std::string site_file;  // position priors' origin and this camera's pixel size ("" = none)
  std::string camera_info_url;   // a calibration ("" = interior below, or EXIF / uncalibrated)
  std::vector<double> interior;  // [] or c x0 y0 k1 k2 k3 p1 p2 b1 b2 (camera::kNumInterior)
  std::string distortion_model = "brown_affinity";
  int sensor_width = 0, sensor_height = 0;  // [px] with interior
  std::string encoding = "auto";            // auto | mono8 | bgr8
  double rate = 2.0;                        // [Hz] folder / video publishing rate
  double start_delay = 1.0;                 // [s]
  double subscriber_wait = 10.0;  // [s] folder / video: wait this long at most for a subscriber
  bool exit_at_end = false;       // folder / video: end the process after the last frame
  double retry_interval = 5.0;    // [s] device: reopen after a failure
  bool continuous = false;        // device: epochs by epoch_gap instead of one per scheduled burst
  std::vector<double> site_origin;  // [] or [lat_deg, lon_deg, height_m]
  capture::FolderSourceOptions folder;
  capture::VideoSourceOptions video;
  capture::DeviceSourceOptions device;
  capture::ScheduleOptions schedule = NodeScheduleOptions();
  capture::EpochOptions epochs;
  FramePublisherOptions publisher;  // source_name, frame_id, pixel_size, gnss, camera_info, ...
  std::string source_description;  // "folder <path>", "video <path>", "V4L2 <device>" (diagnostics)
};

// `node_namespace`: the node handle's namespace (source_name's default is
// its camera, ros/uav_topics.h CameraOfNamespace).
CaptureParameters ReadCaptureParameters(ParamReader& p, const std::string& node_namespace);

}  // namespace ros_adapters
}  // namespace slope_monitor
