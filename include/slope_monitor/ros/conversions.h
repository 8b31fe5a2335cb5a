// Conversions between core types and ROS messages. Only here and in the
// nodelets do core types meet messages.
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/common/rigid3.h"

namespace slope_monitor {
namespace ros_adapters {

camera::CameraInfoFields FromMsg(const sensor_msgs::CameraInfo& msg);
sensor_msgs::CameraInfo ToMsg(const camera::CameraInfoFields& fields);

// Camera model from a CameraInfo (throws InvalidArgument naming what it cannot represent).
camera::CameraModel CameraModelFromCameraInfo(const sensor_msgs::CameraInfo& msg,
                                              double pixel_size);

// A cloud of `n` points in header.frame_id, one FLOAT32 field per name in
// that order (as PointCloud2Modifier::setPointCloud2Fields lays them out:
// height 1, packed, little-endian); `row(i, values)` writes point i's
// fields.size() values.
sensor_msgs::PointCloud2 MakeFloatCloud(const std_msgs::Header& header,
                                        const std::vector<std::string>& fields, std::size_t n,
                                        const std::function<void(std::size_t, float*)>& row);

geometry_msgs::Pose ToPose(const Rigid3& t);
geometry_msgs::Transform ToTransform(const Rigid3& t);
Rigid3 FromPose(const geometry_msgs::Pose& pose);

template <int N>
std::array<double, static_cast<std::size_t>(N) * N> ToRowMajor(
    const Eigen::Matrix<double, N, N>& m) {
  std::array<double, static_cast<std::size_t>(N) * N> out{};
  for (int r = 0; r < N; ++r)
    for (int c = 0; c < N; ++c) out[N * r + c] = m(r, c);
  return out;
}

template <int N, typename Array>
Eigen::Matrix<double, N, N> FromRowMajor(const Array& a) {
  Eigen::Matrix<double, N, N> m;
  for (int r = 0; r < N; ++r)
    for (int c = 0; c < N; ++c) m(r, c) = a[N * r + c];
  return m;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
