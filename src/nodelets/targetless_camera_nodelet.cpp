// targetless_camera: the site's fixed cameras of kind fixed_targetless
// (doc/targetless_camera.md). Thin wrapper around
// ros_adapters::TargetlessCameras (the same code process_bag runs), which
// runs core dense::TargetlessCamera (the track_camera tool's chain):
//   subscribes  /<camera>/camera/image_raw, /<camera>/camera/camera_info
//               for every fixed_targetless camera of `site_file`
//   publishes   displacements  slope_monitor/PointDisplacementArray, source
//                              FEATURE, one point "<camera>/p<probe>" per
//                              usable probe of the monitored area (the
//                              deformation estimator fuses them)
//               /tf            site -> <camera>_optical, the re-oriented pose
//               /diagnostics   "targetless_camera: <camera>": rotation, the
//                              angles' changes and sigmas, rms px, the field's
//                              counts and flags; WARN naming the camera and
//                              the angle above max_rotation_deg
// Parameters: config/defaults/targetless_camera.yaml.
#include <map>
#include <memory>
#include <mutex>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_ros/transform_broadcaster.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/targetless_camera.h"

namespace slope_monitor {

class TargetlessCameraNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          params_ = ros_adapters::ReadTargetlessParameters(p);
          p.CheckNoUnknownKeys();
          cameras_ = std::make_unique<ros_adapters::TargetlessCameras>(params_);
        })) {
      NODELET_ERROR("targetless_camera: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "targetless_camera", "parameters rejected: " + *error);
      return;
    }
    if (cameras_->cameras().empty())
      NODELET_WARN("targetless_camera: site file '%s' has no fixed_targetless camera: idle",
                   params_.site_file.c_str());
    // Under the node's own name (/targetless_camera/displacements), next to its parameters.
    displacements_pub_ = pnh.advertise<slope_monitor::PointDisplacementArray>("displacements", 4);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 4);
    for (const std::string& c : cameras_->cameras()) {
      subs_.push_back(nh.subscribe<sensor_msgs::Image>(
          "/" + c + "/camera/image_raw", 2, [this, c](const sensor_msgs::ImageConstPtr& m) {
            Handle(c, [&] { return cameras_->AddImage(c, m); });
          }));
      subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          "/" + c + "/camera/camera_info", 2, [this, c](const sensor_msgs::CameraInfoConstPtr& m) {
            Handle(c, [&] { return cameras_->AddCameraInfo(c, m); });
          }));
    }
  }

  template <typename F>
  void Handle(const std::string& camera, F add) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<ros_adapters::TargetlessOutputs> out;
    try {
      out = add();
    } catch (const std::exception& e) {
      NODELET_ERROR_THROTTLE(10, "targetless_camera: dropped a photo of '%s': %s", camera.c_str(),
                             e.what());
      diagnostic_msgs::DiagnosticArray d;
      d.header.stamp = ros::Time::now();
      d.status.resize(1);
      d.status[0].name = "targetless_camera: " + camera;
      d.status[0].level = diagnostic_msgs::DiagnosticStatus::ERROR;
      d.status[0].message = e.what();
      diagnostics_pub_.publish(d);
      return;
    }
    if (!out) return;
    NODELET_INFO("targetless_camera: %s", out->info.c_str());
    for (const std::string& w : out->warnings) NODELET_WARN("targetless_camera: %s", w.c_str());
    diagnostic_msgs::DiagnosticArray d;
    d.header.stamp = ros::Time::now();
    d.status.push_back(out->status);
    diagnostics_pub_.publish(d);
    if (out->site_from_optical) tf_.sendTransform(*out->site_from_optical);
    if (out->displacements) displacements_pub_.publish(*out->displacements);
  }

  ros_adapters::TargetlessParameters params_;
  std::unique_ptr<ros_adapters::TargetlessCameras> cameras_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics> setup_failure_;
  ros::Publisher displacements_pub_, diagnostics_pub_;
  std::vector<ros::Subscriber> subs_;
  tf2_ros::TransformBroadcaster tf_;
  std::mutex mutex_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::TargetlessCameraNodelet, nodelet::Nodelet)
