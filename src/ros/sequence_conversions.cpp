#include "slope_monitor/ros/sequence_conversions.h"

#include <cmath>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/image_limits.h"

namespace slope_monitor {
namespace ros_adapters {

cv::Mat ImageForMatching(const sensor_msgs::ImageConstPtr& msg) {
  CheckImageMessage(*msg);
  if (sensor_msgs::image_encodings::numChannels(msg->encoding) == 1)
    return cv_bridge::toCvShare(msg)->image;
  return cv_bridge::toCvShare(msg, sensor_msgs::image_encodings::MONO8)->image;
}

matching::SequencePrior FromPriorMsg(const geometry_msgs::PoseWithCovarianceStamped& msg) {
  matching::SequencePrior out;
  out.position = Eigen::Vector2d(msg.pose.pose.position.x, msg.pose.pose.position.y);
  const auto& o = msg.pose.pose.orientation;
  const Eigen::Quaterniond q(o.w, o.x, o.y, o.z);
  constexpr double kMaxVariance = (30.0 * kRadPerDeg) * (30.0 * kRadPerDeg);
  bool attitude = q.coeffs().allFinite() && std::abs(q.norm() - 1.0) < 1e-3;
  for (int k = 3; k < 6; ++k) {
    const double v = msg.pose.covariance[6 * k + k];
    attitude = attitude && std::isfinite(v) && v > 0.0 && v <= kMaxVariance;
  }
  if (attitude) out.site_from_optical = q;
  return out;
}

namespace {

// A least-squares matched point (a matching::SequenceTie or HexMatch) as a
// TiePoint: pixels, covariance of xb row-major, correlation, quality.
template <typename Match>
slope_monitor::TiePoint LscTiePoint(const Match& t) {
  slope_monitor::TiePoint p;
  p.xa = t.xa.x();
  p.ya = t.xa.y();
  p.xb = t.xb.x();
  p.yb = t.xb.y();
  p.covariance = {t.covariance(0, 0), t.covariance(0, 1), t.covariance(1, 0), t.covariance(1, 1)};
  p.correlation = t.correlation;
  p.quality = t.quality;
  p.method = slope_monitor::TiePoint::METHOD_LSC;
  return p;
}

}  // namespace

slope_monitor::TiePointArray ToMsg(const matching::SequencePair& pair, const std::string& camera) {
  slope_monitor::TiePointArray out;
  out.header.stamp = ToRosTime(pair.stamp_b);
  out.header.frame_id = pair.frame_b;
  if (pair.has_a) {
    out.header_a.stamp = ToRosTime(pair.stamp_a);
    out.header_a.frame_id = pair.frame_a;
    out.camera_a = camera;
    out.epoch_a = pair.epoch;
  }
  out.camera_b = camera;
  out.epoch_b = pair.epoch;
  out.pairs_b = pair.pairs_b;
  out.points.reserve(pair.points.size());
  for (const matching::SequenceTie& t : pair.points) {
    out.points.push_back(LscTiePoint(t));
    out.points.back().id = t.id;
  }
  return out;
}

slope_monitor::TiePointArray ToMsg(const matching::HexMatchResult& result,
                                   const std_msgs::Header& header_a,
                                   const std_msgs::Header& header_b, const std::string& camera_a,
                                   const std::string& camera_b) {
  slope_monitor::TiePointArray out;
  out.header = header_b;
  out.header_a = header_a;
  out.camera_a = camera_a;
  out.camera_b = camera_b;
  for (const matching::HexMatch& m : result.matches) out.points.push_back(LscTiePoint(m));
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
