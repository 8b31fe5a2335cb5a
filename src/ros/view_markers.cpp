#include "slope_monitor/ros/view_markers.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <tf2_eigen/tf2_eigen.h>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

std_msgs::ColorRGBA Rgba(double r, double g, double b) {
  std_msgs::ColorRGBA c;
  c.r = static_cast<float>(r);
  c.g = static_cast<float>(g);
  c.b = static_cast<float>(b);
  c.a = 1.0f;
  return c;
}

visualization_msgs::Marker DeleteAll(const std_msgs::Header& header) {
  visualization_msgs::Marker clear;
  clear.header = header;
  clear.action = visualization_msgs::Marker::DELETEALL;
  return clear;
}

std::string Label(double value) {
  if (std::abs(value) < 5e-3) return "0.0 m";
  char text[32];
  std::snprintf(text, sizeof text, "%+.1f m", value);
  return text;
}

}  // namespace

void FrustumOptions::Check() const {
  if (!(depth > 0.0 && std::isfinite(depth)))
    throw ConfigError(Message("frustum depth must be > 0 m (got ", depth, ")"));
  if (!(line_width > 0.0 && std::isfinite(line_width)))
    throw ConfigError(Message("frustum line width must be > 0 m (got ", line_width, ")"));
}

std::array<Eigen::Vector3d, 4> FrustumCornersInOptical(const camera::Sensor& sensor,
                                                       double principal_distance, double x0,
                                                       double y0, double depth) {
  const double half_w = 0.5 * sensor.width * sensor.pixel_size;   // [mm]
  const double half_h = 0.5 * sensor.height * sensor.pixel_size;  // [mm]
  const double s = depth / principal_distance;
  // Image coordinates (mm, x right, y up) of the corners as seen in the image.
  const std::array<Eigen::Vector2d, 4> xy = {
      Eigen::Vector2d(-half_w, half_h), Eigen::Vector2d(half_w, half_h),
      Eigen::Vector2d(half_w, -half_h), Eigen::Vector2d(-half_w, -half_h)};
  std::array<Eigen::Vector3d, 4> out;
  for (size_t i = 0; i < 4; ++i)
    out[i] = Eigen::Vector3d(s * (xy[i].x() - x0), -s * (xy[i].y() - y0), depth);
  return out;
}

visualization_msgs::MarkerArray ToFrustumMarkers(
    const slope_monitor::AdjustmentSolution& solution,
    const std::map<std::string, camera::CameraModel>& models, const FrustumOptions& options) {
  visualization_msgs::MarkerArray out;
  out.markers.push_back(DeleteAll(solution.header));
  for (size_t i = 0; i < solution.cameras.size(); ++i) {
    const slope_monitor::CameraEstimate& e = solution.cameras[i];
    const auto model = models.find(e.camera_name);
    if (model == models.end() || e.principal_distance <= 0.0) continue;
    const Rigid3 site_from_optical = FromPose(e.site_from_optical);
    const Eigen::Vector3d apex = site_from_optical * Eigen::Vector3d::Zero();
    std::array<Eigen::Vector3d, 4> corners = FrustumCornersInOptical(
        model->second.sensor(), e.principal_distance, e.x0, e.y0, options.depth);
    for (Eigen::Vector3d& c : corners) c = site_from_optical * c;
    visualization_msgs::Marker m;
    m.header = solution.header;
    m.ns = "frustums";
    m.id = static_cast<int>(i);
    m.type = visualization_msgs::Marker::LINE_LIST;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = options.line_width;
    m.color = adjustment::IsUavCamera(e.camera_name, options.uav_cameras) ? Rgba(1.0, 0.55, 0.0)
                                                                          : Rgba(0.2, 1.0, 0.3);
    for (size_t k = 0; k < 4; ++k) {
      m.points.push_back(tf2::toMsg(apex));
      m.points.push_back(tf2::toMsg(corners[k]));
      m.points.push_back(tf2::toMsg(corners[k]));
      m.points.push_back(tf2::toMsg(corners[(k + 1) % 4]));
    }
    out.markers.push_back(std::move(m));
  }
  return out;
}

void ChangeScaleOptions::Check() const {
  if (!(std::isfinite(min) && std::isfinite(max) && min < max))
    throw ConfigError(
        Message("change colour scale: min (", min, " m) must be below max (", max, " m)"));
  if (steps < 2 || steps > 100)
    throw ConfigError(Message("change colour scale: steps must be in 2..100 (got ", steps, ")"));
  if (labels < 2 || labels > 21)
    throw ConfigError(Message("change colour scale: labels must be in 2..21 (got ", labels, ")"));
}

std_msgs::ColorRGBA RvizRainbow(double t) {
  // rviz maps t to a hue from magenta to red in five linear segments.
  const double h = std::clamp(t, 0.0, 1.0) * 5.0 + 1.0;
  const int i = static_cast<int>(std::floor(h));
  double f = h - i;
  if (i % 2 == 0) f = 1.0 - f;
  const double n = 1.0 - f;
  if (i <= 1) return Rgba(n, 0.0, 1.0);
  if (i == 2) return Rgba(0.0, n, 1.0);
  if (i == 3) return Rgba(0.0, 1.0, n);
  if (i == 4) return Rgba(n, 1.0, 0.0);
  return Rgba(1.0, n, 0.0);
}

visualization_msgs::MarkerArray ToChangeScaleMarkers(const ChangeScaleOptions& o,
                                                     const Eigen::Vector3d& base_in_frame,
                                                     double height,
                                                     const std_msgs::Header& header) {
  visualization_msgs::MarkerArray out;
  out.markers.push_back(DeleteAll(header));
  const double cube = height / o.steps;  // [m] edge of a cube, bar as wide as a cube
  for (int k = 0; k < o.steps; ++k) {
    visualization_msgs::Marker m;
    m.header = header;
    m.ns = "change_scale";
    m.id = k;
    m.type = visualization_msgs::Marker::CUBE;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.position =
        tf2::toMsg(Eigen::Vector3d(base_in_frame + Eigen::Vector3d(0, 0, (k + 0.5) * cube)));
    m.pose.orientation.w = 1.0;
    m.scale.x = m.scale.y = m.scale.z = cube;
    m.color = RvizRainbow((k + 0.5) / o.steps);
    out.markers.push_back(std::move(m));
  }
  visualization_msgs::Marker text;
  text.header = header;
  text.ns = "change_scale_labels";
  text.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
  text.action = visualization_msgs::Marker::ADD;
  text.pose.orientation.w = 1.0;
  text.scale.z = 0.6 * cube;
  text.color = Rgba(1.0, 1.0, 1.0);
  for (int k = 0; k < o.labels; ++k) {
    const double t = static_cast<double>(k) / (o.labels - 1);
    text.id = k;
    text.text = Label(o.min + t * (o.max - o.min));
    text.pose.position =
        tf2::toMsg(Eigen::Vector3d(base_in_frame + Eigen::Vector3d(2.2 * cube, 0, t * height)));
    out.markers.push_back(text);
  }
  text.id = o.labels;
  text.text = "change [m]";
  text.pose.position =
      tf2::toMsg(Eigen::Vector3d(base_in_frame + Eigen::Vector3d(0, 0, height + cube)));
  out.markers.push_back(text);
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
