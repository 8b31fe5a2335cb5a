#include "slope_monitor/ros/adjustment_conversions.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"

namespace slope_monitor {
namespace ros_adapters {

namespace {

uint8_t RoleToMsg(adjustment::PointRole r) {
  switch (r) {
    case adjustment::PointRole::kControl:
      return slope_monitor::PointEstimate::ROLE_CONTROL;
    case adjustment::PointRole::kMonitoring:
      return slope_monitor::PointEstimate::ROLE_MONITORING;
    case adjustment::PointRole::kCheck:
      return slope_monitor::PointEstimate::ROLE_CHECK;
    default:
      return slope_monitor::PointEstimate::ROLE_TIE;
  }
}

}  // namespace

adjustment::StampNs ToStamp(const ros::Time& t) { return adjustment::MakeStamp(t.sec, t.nsec); }

ros::Time ToRosTime(adjustment::StampNs stamp) {
  ros::Time t;
  t.fromNSec(static_cast<uint64_t>(stamp));
  return t;
}

adjustment::ImageTargets FromMsg(const slope_monitor::TargetObservationArray& msg) {
  adjustment::ImageTargets out;
  out.camera = msg.camera_name;
  out.frame_id = msg.header.frame_id;
  out.stamp = ToStamp(msg.header.stamp);
  out.epoch = msg.epoch;
  out.targets.reserve(msg.observations.size());
  for (const auto& o : msg.observations)
    out.targets.push_back(
        {o.id, o.family, Eigen::Vector2d(o.x, o.y), FromRowMajor<2>(o.covariance)});
  return out;
}

adjustment::ImageTies FromMsg(const slope_monitor::TiePointArray& msg) {
  adjustment::ImageTies out;
  out.camera_a = msg.camera_a;
  out.camera_b = msg.camera_b;
  out.frame_a = msg.header_a.frame_id;
  out.frame_b = msg.header.frame_id;
  out.stamp_a = ToStamp(msg.header_a.stamp);
  out.stamp_b = ToStamp(msg.header.stamp);
  out.pairs_b = msg.pairs_b;
  out.points.reserve(msg.points.size());
  for (const auto& t : msg.points)
    out.points.push_back({static_cast<int64_t>(t.id), t.quality, Eigen::Vector2d(t.xa, t.ya),
                          Eigen::Vector2d(t.xb, t.yb), FromRowMajor<2>(t.covariance)});
  return out;
}

adjustment::PositionPrior FromMsg(const geometry_msgs::PoseWithCovarianceStamped& msg) {
  adjustment::PositionPrior out;
  out.stamp = ToStamp(msg.header.stamp);
  out.position =
      Eigen::Vector3d(msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) out.covariance(r, k) = msg.pose.covariance[6 * r + k];
  // The orientation part (an attitude from the flight log) as it is; the
  // scene decides whether it is good enough to start from.
  const auto& q = msg.pose.pose.orientation;
  out.site_from_optical = Eigen::Quaterniond(q.w, q.x, q.y, q.z);
  for (int k = 0; k < 3; ++k) out.attitude_variance[k] = msg.pose.covariance[6 * (3 + k) + 3 + k];
  return out;
}

adjustment::EpochEnd FromMsg(const slope_monitor::EpochMarker& msg) {
  if (!msg.end)
    throw InvalidArgument("EpochMarker of '" + msg.source + "' is a start marker, not an end");
  return {msg.source, ToStamp(msg.header.stamp), msg.epoch, msg.count};
}

slope_monitor::AdjustmentSolution MakeSolution(const adjustment::CollectedEpoch& epoch,
                                               const adjustment::Scene& scene,
                                               const adjustment::Summary& s,
                                               const std::string& frame_id) {
  slope_monitor::AdjustmentSolution out;
  out.header.frame_id = frame_id;
  out.header.stamp = ToRosTime(epoch.latest_stamp);
  out.epoch = epoch.epoch;
  out.usable = s.IsSolutionUsable();
  out.message = s.reason;
  out.sigma0 = s.sigma0;
  out.rms_residual_px = s.rms_residual_px;
  out.initial_cost = s.initial_cost;
  out.final_cost = s.final_cost;
  out.iterations = static_cast<uint32_t>(std::max(0, s.iterations));
  out.num_observations = static_cast<uint32_t>(s.num_observations);
  out.num_outliers = static_cast<uint32_t>(s.num_outliers);
  out.solve_time = s.solve_time;
  if (!s.IsSolutionUsable()) return out;
  std::vector<int> obs_per_image(scene.images.size(), 0), obs_per_point(scene.points.size(), 0);
  for (const auto& o : scene.observations) {
    ++obs_per_image[o.image];
    ++obs_per_point[o.point];
  }
  for (size_t i = 0; i < scene.images.size(); ++i) {
    const adjustment::Image& im = scene.images[i];
    const adjustment::Camera& cam = scene.cameras[im.camera];
    slope_monitor::CameraEstimate c;
    c.camera_name = cam.name;
    auto it = epoch.images.find(im.name);
    if (it != epoch.images.end()) {
      c.image_header.stamp = ToRosTime(it->second.stamp);
      c.image_header.frame_id = it->second.frame_id;
    }
    c.site_from_optical = ToPose(im.exterior.SiteFromOptical());
    for (int r = 0; r < 6; ++r)
      for (int k = 0; k < 6; ++k)
        c.pose_covariance[6 * r + k] = s.precision.exterior_covariance[i](r, k);
    c.theta = im.exterior.angles.theta;
    c.phi = im.exterior.angles.phi;
    c.kappa = im.exterior.angles.kappa;
    const auto& in = cam.model.interior();
    c.principal_distance = in[camera::kC];
    c.x0 = in[camera::kX0];
    c.y0 = in[camera::kY0];
    c.distortion.assign(in.begin() + camera::kK1, in.end());
    const auto& sig = s.precision.interior_sigma[im.camera];
    c.interior_sigma.assign(sig.begin(), sig.end());
    c.num_observations = static_cast<uint32_t>(obs_per_image[i]);
    c.rms_residual_px = s.image_rms_px[i];
    out.cameras.push_back(c);
  }
  for (size_t j = 0; j < scene.points.size(); ++j) {
    slope_monitor::PointEstimate p;
    p.id = scene.points[j].id;
    p.role = RoleToMsg(scene.points[j].role);
    p.position.x = scene.points[j].position.x();
    p.position.y = scene.points[j].position.y();
    p.position.z = scene.points[j].position.z();
    const auto cov = ToRowMajor<3>(Eigen::Matrix3d(s.precision.point_covariance[j]));
    std::copy(cov.begin(), cov.end(), p.covariance.begin());
    p.num_observations = static_cast<uint32_t>(obs_per_point[j]);
    out.points.push_back(p);
  }
  return out;
}

sensor_msgs::PointCloud2 MakePointCloud(const adjustment::Scene& scene,
                                        const adjustment::Summary& s,
                                        const std_msgs::Header& header) {
  return MakeFloatCloud(header, {"x", "y", "z", "sigma_x", "sigma_y", "sigma_z"},
                        scene.points.size(), [&](size_t j, float* v) {
                          const Eigen::Matrix3d& c = s.precision.point_covariance[j];
                          v[0] = static_cast<float>(scene.points[j].position.x());
                          v[1] = static_cast<float>(scene.points[j].position.y());
                          v[2] = static_cast<float>(scene.points[j].position.z());
                          v[3] = static_cast<float>(std::sqrt(std::max(0.0, c(0, 0))));
                          v[4] = static_cast<float>(std::sqrt(std::max(0.0, c(1, 1))));
                          v[5] = static_cast<float>(std::sqrt(std::max(0.0, c(2, 2))));
                        });
}

CameraTransforms MakeTransforms(const adjustment::Scene& scene,
                                const adjustment::CollectedEpoch& epoch,
                                const std::string& frame_id, const ros::Time& stamp,
                                const std::set<std::string>& moving_cameras) {
  CameraTransforms tfs;
  std::set<std::string> done;
  // The latest image of each fixed camera defines its frame; every image of a
  // moving camera is its own stamped transform.
  for (auto it = scene.images.rbegin(); it != scene.images.rend(); ++it) {
    auto ci = epoch.images.find(it->name);
    const std::string& camera = scene.cameras[it->camera].name;
    const std::string frame = ci != epoch.images.end() ? ci->second.frame_id : camera + "_optical";
    const bool moving = moving_cameras.count(camera) > 0;
    if (!moving && !done.insert(frame).second) continue;
    geometry_msgs::TransformStamped t;
    t.header.stamp = stamp;
    if (moving && ci != epoch.images.end())
      t.header.stamp.fromNSec(static_cast<uint64_t>(ci->second.stamp));
    t.header.frame_id = frame_id;
    t.child_frame_id = frame;
    t.transform = ToTransform(it->exterior.SiteFromOptical());
    (moving ? tfs.moving : tfs.fixed).push_back(t);
  }
  // Time order for the moving ones (a tf buffer accepts them in any order; readers prefer it).
  std::reverse(tfs.moving.begin(), tfs.moving.end());
  return tfs;
}

std::vector<geometry_msgs::TransformStamped> MakeTransforms(const adjustment::Scene& scene,
                                                            const adjustment::CollectedEpoch& epoch,
                                                            const std::string& frame_id,
                                                            const ros::Time& stamp) {
  return MakeTransforms(scene, epoch, frame_id, stamp, {}).fixed;
}

slope_monitor::PointDisplacementArray MakeDisplacements(
    const adjustment::EpochComparison& comparison, const adjustment::EpochPoints& reference,
    int epoch, const std::string& source_name, const std_msgs::Header& header) {
  slope_monitor::PointDisplacementArray msg;
  msg.header = header;
  msg.epoch = static_cast<uint32_t>(epoch);
  for (const adjustment::Displacement& d : comparison.displacements) {
    slope_monitor::PointDisplacement p = MakePointDisplacement(
        d.id, slope_monitor::PointDisplacement::SOURCE_TARGET, source_name, reference.stamp,
        header.stamp, d.reference_position, d.displacement, d.covariance);
    p.significance = d.significance;
    msg.displacements.push_back(p);
  }
  return msg;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
