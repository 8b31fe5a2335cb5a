// process_bag's dense epoch step (doc/process_bag.md, doc/dense_change.md):
// the same ros_adapters::DenseEpochStep the dense_epoch nodelet runs, fed in
// bag-time order in one thread. Photos and camera_info of the surface
// cameras are collected; each solution's epoch is measured as soon as its
// photos are there (at the end of the bags with what it has, the missing
// photos named), its output handed to `write` (cloud: /dense/surface_cloud,
// areas of significant change: /dense/change_areas, colour scale of the
// cloud's change: /dense/change_legend)
// and its GeoTIFFs written to the report directory.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/ros/dense_epoch_step.h"

namespace slope_monitor {
namespace ros_adapters {

class OfflineDense {
 public:
  // The graph's cloud topic (launch/include/processing_graph.xml).
  static constexpr char kCloudTopic[] = "/dense/surface_cloud";
  static constexpr char kAreasTopic[] = "/dense/change_areas";
  static constexpr char kLegendTopic[] = "/dense/change_legend";

  // `params`: the node's keys (config/defaults/dense_epoch.yaml and what the
  // launch files add), read as the node reads them; ConfigError naming the key.
  OfflineDense(const XmlRpc::XmlRpcValue& params,
               std::function<void(const DenseEpochOutput&)> write,
               std::function<void(const std::string&)> log);

  // `now` [s]: bag time.
  void OnImage(const std::string& camera, const sensor_msgs::Image& image, double now);
  void OnCameraInfo(const std::string& camera, const sensor_msgs::CameraInfo& info);
  void OnSolution(const slope_monitor::AdjustmentSolution& solution, double now);
  void Finish();  // end of the bags

  int epochs_measured() const { return epochs_; }
  double seconds() const { return seconds_; }          // wall time spent measuring
  double cpu_seconds() const { return cpu_seconds_; }  // process CPU time spent measuring

 private:
  bool Camera(const std::string& camera) const;
  void Measure(const std::vector<dense::PhotoEpoch>& epochs);
  void Log(const std::vector<LogLine>& lines);

  std::vector<std::string> cameras_;
  std::unique_ptr<DenseEpochStep> step_;
  std::function<void(const DenseEpochOutput&)> write_;
  std::function<void(const std::string&)> log_;
  int epochs_ = 0;
  double seconds_ = 0.0, cpu_seconds_ = 0.0;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
