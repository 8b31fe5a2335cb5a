#include "slope_monitor/ros/change_area_conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

geometry_msgs::Polygon ToRing(const dense::Polygon& ring) {
  geometry_msgs::Polygon out;
  for (const Eigen::Vector2d& v : ring) {
    geometry_msgs::Point32 p;
    p.x = static_cast<float>(v.x());
    p.y = static_cast<float>(v.y());
    out.points.push_back(p);
  }
  return out;
}

std::vector<Eigen::Vector2d> FromRing(const geometry_msgs::Polygon& ring) {
  std::vector<Eigen::Vector2d> out;
  for (const geometry_msgs::Point32& p : ring.points) out.emplace_back(p.x, p.y);
  return out;
}

}  // namespace

slope_monitor::ChangeAreaArray ToChangeAreaMsg(const std::vector<dense::ChangePolygon>& polygons,
                                               uint32_t epoch, uint32_t reference_epoch,
                                               const std_msgs::Header& header) {
  slope_monitor::ChangeAreaArray msg;
  msg.header = header;
  msg.epoch = epoch;
  msg.reference_epoch = reference_epoch;
  for (const dense::ChangePolygon& p : polygons) {
    slope_monitor::ChangeArea a;
    a.sign = static_cast<int8_t>(p.sign);
    a.area = p.area;
    a.volume = p.volume;
    a.mean_change = p.mean_change;
    a.max_change = p.max_change;
    a.outline = ToRing(p.outline);
    for (const dense::Polygon& h : p.holes) a.holes.push_back(ToRing(h));
    msg.areas.push_back(a);
  }
  return msg;
}

deformation::AreaBatch AreaBatchFromMsg(const slope_monitor::ChangeAreaArray& msg,
                                        const std::string& source_name) {
  deformation::AreaBatch b;
  b.epoch = msg.epoch;
  b.reference_epoch = msg.reference_epoch;
  b.stamp = msg.header.stamp.toSec();
  b.source_name = source_name;
  for (const slope_monitor::ChangeArea& m : msg.areas) {
    deformation::ChangeArea a;
    a.sign = m.sign;  // NOLINT(bugprone-signed-char-misuse): an int8 number, +1 or -1
    a.area = m.area;
    a.volume = m.volume;
    a.mean_change = m.mean_change;
    a.max_change = m.max_change;
    a.outline = FromRing(m.outline);
    for (const geometry_msgs::Polygon& h : m.holes) a.holes.push_back(FromRing(h));
    b.areas.push_back(std::move(a));
  }
  return b;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
