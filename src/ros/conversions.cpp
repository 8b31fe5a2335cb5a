#include "slope_monitor/ros/conversions.h"

#include <cstring>

#include <sensor_msgs/point_cloud2_iterator.h>

namespace slope_monitor {
namespace ros_adapters {

camera::CameraInfoFields FromMsg(const sensor_msgs::CameraInfo& msg) {
  camera::CameraInfoFields f;
  f.width = static_cast<int>(msg.width);
  f.height = static_cast<int>(msg.height);
  f.distortion_model = msg.distortion_model;
  f.d = msg.D;
  for (int i = 0; i < 9; ++i) {
    f.k[i] = msg.K[i];
    f.r[i] = msg.R[i];
  }
  for (int i = 0; i < 12; ++i) f.p[i] = msg.P[i];
  return f;
}

sensor_msgs::CameraInfo ToMsg(const camera::CameraInfoFields& f) {
  sensor_msgs::CameraInfo msg;
  msg.width = static_cast<uint32_t>(f.width);
  msg.height = static_cast<uint32_t>(f.height);
  msg.distortion_model = f.distortion_model;
  msg.D = f.d;
  for (int i = 0; i < 9; ++i) {
    msg.K[i] = f.k[i];
    msg.R[i] = f.r[i];
  }
  for (int i = 0; i < 12; ++i) msg.P[i] = f.p[i];
  return msg;
}

camera::CameraModel CameraModelFromCameraInfo(const sensor_msgs::CameraInfo& msg,
                                              double pixel_size) {
  return camera::CameraModel::FromCameraInfo(FromMsg(msg), pixel_size);
}

sensor_msgs::PointCloud2 MakeFloatCloud(const std_msgs::Header& header,
                                        const std::vector<std::string>& fields, std::size_t n,
                                        const std::function<void(std::size_t, float*)>& row) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header = header;
  for (std::size_t k = 0; k < fields.size(); ++k) {
    sensor_msgs::PointField f;
    f.name = fields[k];
    f.offset = static_cast<uint32_t>(k * sizeof(float));
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    cloud.fields.push_back(f);
  }
  cloud.point_step = static_cast<uint32_t>(fields.size() * sizeof(float));
  sensor_msgs::PointCloud2Modifier(cloud).resize(n);
  std::vector<float> values(fields.size());
  for (std::size_t i = 0; i < n; ++i) {
    row(i, values.data());
    std::memcpy(&cloud.data[i * cloud.point_step], values.data(), cloud.point_step);
  }
  return cloud;
}

geometry_msgs::Pose ToPose(const Rigid3& t) {
  geometry_msgs::Pose p;
  p.position.x = t.translation.x();
  p.position.y = t.translation.y();
  p.position.z = t.translation.z();
  p.orientation.w = t.rotation.w();
  p.orientation.x = t.rotation.x();
  p.orientation.y = t.rotation.y();
  p.orientation.z = t.rotation.z();
  return p;
}

geometry_msgs::Transform ToTransform(const Rigid3& t) {
  geometry_msgs::Transform tf;
  tf.translation.x = t.translation.x();
  tf.translation.y = t.translation.y();
  tf.translation.z = t.translation.z();
  tf.rotation.w = t.rotation.w();
  tf.rotation.x = t.rotation.x();
  tf.rotation.y = t.rotation.y();
  tf.rotation.z = t.rotation.z();
  return tf;
}

Rigid3 FromPose(const geometry_msgs::Pose& p) {
  return Rigid3(
      Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z),
      Eigen::Vector3d(p.position.x, p.position.y, p.position.z));
}

}  // namespace ros_adapters
}  // namespace slope_monitor
