// The UAV sequence matcher (core/matching/sequence_matcher.h) at the ROS
// boundary, shared by the hex_matcher nodelet (mode sequence) and process_bag
// --uav-tie-points: images in, TiePointArray messages out.
#pragma once

#include <string>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>
#include <opencv2/core.hpp>

#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/sequence_matcher.h"

namespace slope_monitor {
namespace ros_adapters {

// The image as the matchers take it: one channel kept (shared with the
// message), colour converted to mono8. Throws cv_bridge's exception for an
// encoding it cannot convert.
cv::Mat ImageForMatching(const sensor_msgs::ImageConstPtr& msg);

// A UAV photo's position_prior for the sequence matcher: x, y, and the
// orientation (site_from_optical) when it is an attitude: a unit quaternion
// whose three rotation variances are in (0, (30 deg)^2] (0 is ROS'
// "unknown"). A coarse attitude is enough: it only turns the footprint.
matching::SequencePrior FromPriorMsg(const geometry_msgs::PoseWithCovarianceStamped& msg);

// One pair as the graph publishes it on tie_points: header of image b,
// header_a of image a (none when image b has no partner: camera_a ""),
// camera_a/_b `camera`, epochs, pairs_b, points (id, pixels, covariance
// row-major, correlation, quality, METHOD_LSC).
slope_monitor::TiePointArray ToMsg(const matching::SequencePair& pair, const std::string& camera);

// The hex matcher's pair or track result (core/matching/hex_matcher.h) as it
// publishes it: header of image b, header_a of image a, cameras, points
// (pixels, covariance row-major, correlation, quality, METHOD_LSC; no id).
slope_monitor::TiePointArray ToMsg(const matching::HexMatchResult& result,
                                   const std_msgs::Header& header_a,
                                   const std_msgs::Header& header_b, const std::string& camera_a,
                                   const std::string& camera_b);

}  // namespace ros_adapters
}  // namespace slope_monitor
