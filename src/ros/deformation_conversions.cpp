#include "slope_monitor/ros/deformation_conversions.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <sstream>

#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_eigen/tf2_eigen.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

constexpr double kMmPerDay = 1e3 * 86400.0;

std_msgs::ColorRGBA AlertColour(deformation::AlertLevel a) {
  std_msgs::ColorRGBA c;
  c.a = 1.0;
  switch (a) {
    case deformation::AlertLevel::kWatch:
      c.r = 1.0;
      c.g = 0.85;
      c.b = 0.0;
      break;
    case deformation::AlertLevel::kWarning:
      c.r = 1.0;
      c.g = 0.5;
      c.b = 0.0;
      break;
    case deformation::AlertLevel::kAlarm:
      c.r = 0.95;
      c.g = 0.0;
      c.b = 0.0;
      break;
    default:
      c.r = 0.2;
      c.g = 0.75;
      c.b = 0.2;
  }
  return c;
}

geometry_msgs::Vector3 ToVector(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 p;
  p.x = v.x();
  p.y = v.y();
  p.z = v.z();
  return p;
}

}  // namespace

deformation::Batch FromMsg(const slope_monitor::PointDisplacementArray& msg,
                           const std::string& topic) {
  deformation::Batch b;
  b.epoch = msg.epoch;
  b.stamp = msg.header.stamp.toSec();
  for (const slope_monitor::PointDisplacement& d : msg.displacements) {
    deformation::Measurement m;
    m.point_id = d.point_id;
    try {
      m.source = deformation::SourceFromInt(d.source);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(Message("topic '", topic, "', point '", d.point_id, "': ", e.what()));
    }
    m.source_name = d.source_name.empty() ? topic : d.source_name;
    m.epoch = msg.epoch;
    m.stamp = d.stamp.isZero() ? b.stamp : d.stamp.toSec();
    m.reference_stamp = d.reference_stamp.toSec();
    m.reference_position =
        Eigen::Vector3d(d.reference_position.x, d.reference_position.y, d.reference_position.z);
    m.displacement = Eigen::Vector3d(d.displacement.x, d.displacement.y, d.displacement.z);
    m.covariance = FromRowMajor<3>(d.covariance);
    b.measurements.push_back(m);
  }
  return b;
}

slope_monitor::PointDisplacement MakePointDisplacement(
    const std::string& point_id, uint8_t source, const std::string& source_name,
    double reference_stamp, const ros::Time& stamp, const Eigen::Vector3d& reference_position,
    const Eigen::Vector3d& displacement, const Eigen::Matrix3d& covariance) {
  slope_monitor::PointDisplacement p;
  p.point_id = point_id;
  p.source = source;
  p.source_name = source_name;
  p.reference_stamp = ros::Time(reference_stamp);
  p.stamp = stamp;
  p.reference_position.x = reference_position.x();
  p.reference_position.y = reference_position.y();
  p.reference_position.z = reference_position.z();
  p.displacement.x = displacement.x();
  p.displacement.y = displacement.y();
  p.displacement.z = displacement.z();
  const auto cov = ToRowMajor<3>(covariance);
  std::copy(cov.begin(), cov.end(), p.covariance.begin());
  return p;
}

slope_monitor::SlopeDeformation ToMsg(const deformation::Snapshot& s,
                                      const std_msgs::Header& header) {
  slope_monitor::SlopeDeformation msg;
  msg.header = header;
  msg.epoch = s.epoch;
  msg.reference_epoch = s.reference_epoch;
  msg.reference_stamp = ros::Time(std::max(0.0, s.reference_stamp));
  msg.alert_level = static_cast<uint8_t>(s.alert);
  msg.summary = s.summary;
  for (const deformation::PointState& p : s.points) {
    slope_monitor::DeformationPoint d;
    d.point_id = p.id;
    d.reference_position = tf2::toMsg(p.reference_position);
    d.displacement = ToVector(p.displacement);
    const auto dc = ToRowMajor<3>(p.displacement_covariance);
    std::copy(dc.begin(), dc.end(), d.displacement_covariance.begin());
    d.velocity = ToVector(p.velocity);
    const auto vc = ToRowMajor<3>(p.velocity_covariance);
    std::copy(vc.begin(), vc.end(), d.velocity_covariance.begin());
    d.acceleration = ToVector(p.acceleration);
    d.alert_level = static_cast<uint8_t>(p.alert);
    d.alert_reason = p.alert_reason;
    d.forecast_valid = p.forecast.valid;
    if (p.forecast.valid && p.forecast.failure_time > 0)
      d.forecast_failure_time = ros::Time(p.forecast.failure_time);
    d.forecast_sigma = p.forecast.sigma;
    d.forecast_window = p.forecast.window;
    for (deformation::Source src : p.sources) d.sources.push_back(static_cast<uint8_t>(src));
    d.sources_disagree = p.sources_disagree;
    msg.points.push_back(d);
  }
  return msg;
}

visualization_msgs::MarkerArray ToMarkers(const deformation::Snapshot& s,
                                          const std_msgs::Header& header, const MarkerOptions& o) {
  visualization_msgs::MarkerArray out;
  visualization_msgs::Marker clear;
  clear.header = header;
  clear.action = visualization_msgs::Marker::DELETEALL;
  out.markers.push_back(clear);
  int id = 0;
  for (const deformation::PointState& p : s.points) {
    const std_msgs::ColorRGBA colour = AlertColour(p.alert);
    visualization_msgs::Marker sphere;
    sphere.header = header;
    sphere.ns = "points";
    sphere.id = id;
    sphere.type = visualization_msgs::Marker::SPHERE;
    sphere.action = visualization_msgs::Marker::ADD;
    sphere.pose.position = tf2::toMsg(p.reference_position);
    sphere.pose.orientation.w = 1.0;
    sphere.scale.x = sphere.scale.y = sphere.scale.z = o.point_size;
    sphere.color = colour;
    out.markers.push_back(sphere);

    visualization_msgs::Marker arrow = sphere;
    arrow.ns = "arrows";
    arrow.type = visualization_msgs::Marker::ARROW;
    arrow.pose = geometry_msgs::Pose();
    arrow.pose.orientation.w = 1.0;
    arrow.points.push_back(tf2::toMsg(p.reference_position));
    arrow.points.push_back(
        tf2::toMsg(Eigen::Vector3d(p.reference_position + o.arrow_scale * p.displacement)));
    arrow.scale.x = 0.4 * o.point_size;  // shaft diameter
    arrow.scale.y = 0.8 * o.point_size;  // head diameter
    arrow.scale.z = 0.0;                 // default head length
    out.markers.push_back(arrow);

    visualization_msgs::Marker label = sphere;
    label.ns = "labels";
    label.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    label.pose.position.z += 1.5 * o.point_size + o.text_size;
    label.scale.x = label.scale.y = 0.0;
    label.scale.z = o.text_size;
    label.text = Message(
        p.id, "  ", Fixed(p.displacement.norm() * 1e3, 1), " mm  ", Fixed(p.speed * kMmPerDay, 1),
        " mm/d",
        p.alert == deformation::AlertLevel::kNone ? "" : "  " + deformation::AlertName(p.alert),
        p.sources_disagree ? "  (sources disagree)" : "");
    out.markers.push_back(label);
    ++id;
  }
  return out;
}

sensor_msgs::PointCloud2 ToCloud(const deformation::Snapshot& s, const std_msgs::Header& header) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header = header;
  sensor_msgs::PointCloud2Modifier mod(cloud);
  mod.setPointCloud2Fields(
      5, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32, "z", 1,
      sensor_msgs::PointField::FLOAT32, "displacement", 1, sensor_msgs::PointField::FLOAT32, "rgb",
      1, sensor_msgs::PointField::FLOAT32);
  mod.resize(s.points.size());
  double max_d = 1e-9;
  for (const auto& p : s.points) max_d = std::max(max_d, p.displacement.norm());
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"),
      d(cloud, "displacement");
  sensor_msgs::PointCloud2Iterator<uint8_t> rgb(cloud, "rgb");
  for (const auto& p : s.points) {
    *x = static_cast<float>(p.reference_position.x());
    *y = static_cast<float>(p.reference_position.y());
    *z = static_cast<float>(p.reference_position.z());
    *d = static_cast<float>(p.displacement.norm());
    const double f = std::min(1.0, p.displacement.norm() / max_d);  // blue (still) -> red (largest)
    rgb[0] = static_cast<uint8_t>(std::lround(255 * (1 - f)));      // b
    rgb[1] = static_cast<uint8_t>(std::lround(255 * (1 - std::abs(2 * f - 1))));  // g
    rgb[2] = static_cast<uint8_t>(std::lround(255 * f));                          // r
    rgb[3] = 0;
    ++x, ++y, ++z, ++d, ++rgb;
  }
  return cloud;
}

diagnostic_msgs::DiagnosticArray ToAlerts(const deformation::Snapshot& s,
                                          const std_msgs::Header& header) {
  diagnostic_msgs::DiagnosticArray out;
  out.header = header;
  auto level_of = [](deformation::AlertLevel a) {
    return a == deformation::AlertLevel::kAlarm  ? diagnostic_msgs::DiagnosticStatus::ERROR
           : a == deformation::AlertLevel::kNone ? diagnostic_msgs::DiagnosticStatus::OK
                                                 : diagnostic_msgs::DiagnosticStatus::WARN;
  };
  auto kv = [](const std::string& k, const std::string& v) {
    diagnostic_msgs::KeyValue x;
    x.key = k;
    x.value = v;
    return x;
  };
  diagnostic_msgs::DiagnosticStatus slope;
  slope.name = "deformation/slope";
  slope.hardware_id = "slope";
  slope.level = level_of(s.alert);
  slope.message = Message("alert ", deformation::AlertName(s.alert), ": ", s.summary);
  slope.values.push_back(kv("alert", deformation::AlertName(s.alert)));
  slope.values.push_back(kv("reference_epoch", std::to_string(s.reference_epoch)));
  out.status.push_back(slope);
  for (const deformation::PointState& p : s.points) {
    diagnostic_msgs::DiagnosticStatus st;
    st.name = "deformation/" + p.id;
    st.hardware_id = p.id;
    st.level = level_of(p.alert);
    st.message =
        deformation::AlertName(p.alert) + (p.alert_reason.empty() ? "" : ": " + p.alert_reason);
    st.values.push_back(kv("alert", deformation::AlertName(p.alert)));
    st.values.push_back(kv("displacement_mm", Fixed(p.displacement.norm() * 1e3, 2)));
    st.values.push_back(kv("speed_mm_per_day", Fixed(p.speed * kMmPerDay, 2)));
    st.values.push_back(kv("sigma_speed_mm_per_day", Fixed(p.speed_sigma * kMmPerDay, 2)));
    st.values.push_back(kv("sources_disagree", p.sources_disagree ? "true" : "false"));
    st.values.push_back(kv("forecast_valid", p.forecast.valid ? "true" : "false"));
    if (p.forecast.valid) {
      st.values.push_back(kv("forecast_failure_time", Fixed(p.forecast.failure_time, 0)));
      st.values.push_back(kv("forecast_sigma_h", Fixed(p.forecast.sigma / 3600.0, 2)));
      st.values.push_back(kv("forecast_window_h", Fixed(p.forecast.window / 3600.0, 2)));
    }
    out.status.push_back(st);
  }
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
