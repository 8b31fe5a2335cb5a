// One collected adjustment epoch through the core (BuildScene, AdjustEpoch,
// EpochStore accept and comparison with the reference) into the messages the
// bundle adjuster publishes. Shared by the bundle_adjuster nodelet and the
// process_bag tool, so a replay and an offline run compute and publish the
// same thing; the caller logs `log` and publishes what is set.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/PointCloud2.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/ros/node_parameters.h"

namespace slope_monitor {
namespace ros_adapters {

struct LogLine {
  enum Level { kDebug, kInfo, kWarn, kError } level = kInfo;
  std::string text;  // without the node's name
};

struct SolvedEpoch {
  slope_monitor::AdjustmentSolution solution;  // always published
  bool accepted = false;                       // the rest is set only when accepted
  // Fixed cameras' latest poses (for /tf_static, latched) and each UAV
  // photo's pose stamped with the photo (for /tf).
  std::vector<geometry_msgs::TransformStamped> fixed_transforms, moving_transforms;
  sensor_msgs::PointCloud2 points;
  std::optional<slope_monitor::PointDisplacementArray> displacements;
  std::vector<LogLine> log;
  // For diagnostics (valid when an adjustment ran).
  bool adjusted = false;
  adjustment::PhotoStats photos;
  adjustment::NamingReport naming;
  int rejected_names = 0;
  double covariance_time = 0.0;  // [s] adjustment::Summary::covariance_time
  double wall_time = 0.0;        // [s] of the whole solve (AdjusterStep; process_bag's stage times)
};

// `source_name`: the displacement messages' source (the node's name).
SolvedEpoch SolveCollectedEpoch(const adjustment::CollectedEpoch& epoch,
                                const std::map<std::string, camera::CameraModel>& models,
                                const AdjusterParameters& params, const std::string& source_name,
                                adjustment::EpochStore* store);

}  // namespace ros_adapters
}  // namespace slope_monitor
