// Conversions between the bundle adjuster's messages and the core epoch
// collection / adjustment types, shared by the bundle_adjuster nodelet and the
// process_bag tool (so both read and write the same messages the same way).
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/epochs.h"

namespace slope_monitor {
namespace ros_adapters {

adjustment::StampNs ToStamp(const ros::Time& t);
ros::Time ToRosTime(adjustment::StampNs stamp);

adjustment::ImageTargets FromMsg(const slope_monitor::TargetObservationArray& msg);
adjustment::ImageTies FromMsg(const slope_monitor::TiePointArray& msg);
adjustment::PositionPrior FromMsg(const geometry_msgs::PoseWithCovarianceStamped& msg);
adjustment::EpochEnd FromMsg(const slope_monitor::EpochMarker& msg);  // msg.end must be true

// The solution of an epoch (header stamp: its latest image; cameras and
// points only when the summary is usable).
slope_monitor::AdjustmentSolution MakeSolution(const adjustment::CollectedEpoch& epoch,
                                               const adjustment::Scene& scene,
                                               const adjustment::Summary& summary,
                                               const std::string& frame_id);
// Adjusted points with their sigma (fields x y z sigma_x sigma_y sigma_z).
sensor_msgs::PointCloud2 MakePointCloud(const adjustment::Scene& scene,
                                        const adjustment::Summary& summary,
                                        const std_msgs::Header& header);
// site_from_optical of the cameras: `fixed` holds each fixed camera's latest
// image, stamped `stamp` (for /tf_static); `moving` every image of a camera
// in moving_cameras (UAV photos), each stamped with its own photo time (for
// /tf: the camera's frame moves from photo to photo).
struct CameraTransforms {
  std::vector<geometry_msgs::TransformStamped> fixed, moving;
};
CameraTransforms MakeTransforms(const adjustment::Scene& scene,
                                const adjustment::CollectedEpoch& epoch,
                                const std::string& frame_id, const ros::Time& stamp,
                                const std::set<std::string>& moving_cameras);
// Every camera's latest image, all stamped `stamp` (no moving cameras).
std::vector<geometry_msgs::TransformStamped> MakeTransforms(const adjustment::Scene& scene,
                                                            const adjustment::CollectedEpoch& epoch,
                                                            const std::string& frame_id,
                                                            const ros::Time& stamp);
slope_monitor::PointDisplacementArray MakeDisplacements(
    const adjustment::EpochComparison& comparison, const adjustment::EpochPoints& reference,
    int epoch, const std::string& source_name, const std_msgs::Header& header);

}  // namespace ros_adapters
}  // namespace slope_monitor
