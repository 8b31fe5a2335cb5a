#include "slope_monitor/ros/sequence_step.h"

#include <cstdio>
#include <exception>

#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/sequence_conversions.h"

namespace slope_monitor {
namespace ros_adapters {

SequenceMatcherStep::SequenceMatcherStep(const HexMatcherParameters& parameters)
    : parameters_(parameters), matcher_(parameters_.sequence) {}

SequenceOutput SequenceMatcherStep::AddImage(const sensor_msgs::ImageConstPtr& image, double now) {
  cv::Mat grey;
  std::optional<LogLine> failed;
  try {
    grey = ImageForMatching(image);
  } catch (const std::exception& e) {
    char stamp[32];
    std::snprintf(stamp, sizeof stamp, "%.3f", image->header.stamp.toSec());
    failed = LogLine{LogLine::kError, "image on " + parameters_.image_topic + " at " + stamp +
                                          " not converted: " + e.what()};
  }
  SequenceOutput out =
      Output(matcher_.AddImage(ToStamp(image->header.stamp), image->header.frame_id, grey, now));
  if (failed) out.log.insert(out.log.begin(), *failed);
  return out;
}

std::optional<std::string> SequenceMatcherStep::CheckPrior(
    const geometry_msgs::PoseWithCovarianceStamped& prior) const {
  if (prior.header.frame_id.empty() || prior.header.frame_id == parameters_.site_frame)
    return std::nullopt;
  return parameters_.prior_topic + " in frame '" + prior.header.frame_id + "', expected '" +
         parameters_.site_frame + "' (site_frame); ignored";
}

SequenceOutput SequenceMatcherStep::AddPrior(
    const geometry_msgs::PoseWithCovarianceStamped& prior) {
  return Output(matcher_.AddPrior(ToStamp(prior.header.stamp), FromPriorMsg(prior)));
}

SequenceOutput SequenceMatcherStep::Output(const matching::SequenceStep& step) const {
  SequenceOutput out;
  for (const std::string& line : step.log) out.log.push_back({LogLine::kInfo, line});
  for (const matching::SequencePair& p : step.pairs) {
    if (!p.reason.empty())  // a failure, unless a small flight's all-with-all pair shares no ground
      out.log.push_back(
          {p.expected_to_overlap || p.reason == "error" ? LogLine::kError : LogLine::kDebug,
           "sequence " + p.message + " (empty tie points)"});
    else if (p.has_a)
      out.log.push_back({LogLine::kDebug, "sequence " + p.message + " (" + std::to_string(p.index) +
                                              " of " + std::to_string(p.pairs_b) + ")"});
    out.tie_points.push_back(ToMsg(p, parameters_.camera));
  }
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
