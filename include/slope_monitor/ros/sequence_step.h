// The hex matcher's sequence mode (one moving camera, e.g. a UAV) from ROS
// messages: images and position priors into matching::SequenceMatcher, its
// pairs out as the TiePointArray messages to publish. The hex_matcher
// nodelet (mode sequence, on its worker thread) and process_bag
// (--uav-tie-points, in bag-time order) use this same class.
// Not thread-safe: the caller serialises the calls.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <sensor_msgs/Image.h>

#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/matching/sequence_matcher.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"

namespace slope_monitor {
namespace ros_adapters {

struct SequenceOutput {
  std::vector<slope_monitor::TiePointArray> tie_points;  // one per pair, in order
  // The matcher's lines (kInfo), each matched pair's progress (kDebug) and
  // each pair without tie points (kError), without the node's name.
  std::vector<LogLine> log;
};

class SequenceMatcherStep {
 public:
  // Throws ConfigError (the matcher's options).
  explicit SequenceMatcherStep(const HexMatcherParameters& parameters);

  const HexMatcherParameters& parameters() const { return parameters_; }
  matching::SequenceMatcher& matcher() { return matcher_; }

  // `now` [s]: the caller's clock (Poll's time-out only). An image that
  // cannot be converted goes in empty (the matcher counts it) with a kError line.
  SequenceOutput AddImage(const sensor_msgs::ImageConstPtr& image, double now);
  // Why a prior is not taken (another frame than site_frame); none when it is.
  std::optional<std::string> CheckPrior(
      const geometry_msgs::PoseWithCovarianceStamped& prior) const;
  SequenceOutput AddPrior(const geometry_msgs::PoseWithCovarianceStamped& prior);
  SequenceOutput Poll(double now) { return Output(matcher_.Poll(now)); }
  SequenceOutput Finish() { return Output(matcher_.Finish()); }

 private:
  SequenceOutput Output(const matching::SequenceStep& step) const;

  HexMatcherParameters parameters_;
  matching::SequenceMatcher matcher_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
