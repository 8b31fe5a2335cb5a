#include "slope_monitor/ros/dense_conversions.h"

#include <cmath>
#include <cstdio>
#include <cstring>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace ros_adapters {

dense::EpochImage EpochImageFromEstimate(const slope_monitor::CameraEstimate& e,
                                         const sensor_msgs::Image& image,
                                         const sensor_msgs::CameraInfo& info, double pixel_size,
                                         dense::ImageKind kind) {
  dense::EpochImage out;
  out.kind = kind;
  out.camera = e.camera_name;
  dense::OrientedImage& im = out.image;
  char stamp[32];
  std::snprintf(stamp, sizeof stamp, "%.3f", e.image_header.stamp.toSec());
  im.name = e.camera_name + "@" + stamp;
  im.image = cv_bridge::toCvCopy(image)->image;
  const camera::CameraModel from_info = CameraModelFromCameraInfo(info, pixel_size);
  std::array<double, camera::kNumInterior> interior = from_info.interior();
  if (e.distortion.size() > camera::kNumInterior - 3)
    throw InvalidArgument(Message("camera '", e.camera_name, "': ", e.distortion.size(),
                                  " distortion terms in the solution, at most ",
                                  camera::kNumInterior - 3));
  interior[camera::kC] = e.principal_distance;
  interior[camera::kX0] = e.x0;
  interior[camera::kY0] = e.y0;
  for (size_t i = 0; i < e.distortion.size(); ++i) interior[camera::kK1 + i] = e.distortion[i];
  im.camera = camera::CameraModel(from_info.sensor(), from_info.model(), interior);
  im.pose =
      camera::ExteriorOrientation::FromOpticalFromSite(FromPose(e.site_from_optical).Inverse());
  im.oriented = true;
  return out;
}

std::vector<Eigen::Vector3d> AdjustedPoints(const slope_monitor::AdjustmentSolution& solution) {
  std::vector<Eigen::Vector3d> points;
  for (const slope_monitor::PointEstimate& p : solution.points)
    points.emplace_back(p.position.x, p.position.y, p.position.z);
  return points;
}

sensor_msgs::PointCloud2 MakeSurfaceCloud(const dense::EpochSurfaceResult& surface,
                                          const dense::DemChangeResult* change,
                                          const std_msgs::Header& header) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header = header;
  sensor_msgs::PointCloud2Modifier mod(cloud);
  using sensor_msgs::PointField;
  mod.setPointCloud2Fields(7, "x", 1, PointField::FLOAT32, "y", 1, PointField::FLOAT32, "z", 1,
                           PointField::FLOAT32, "rgb", 1, PointField::FLOAT32, "sigma_z", 1,
                           PointField::FLOAT32, "change", 1, PointField::FLOAT32, "lod", 1,
                           PointField::FLOAT32);
  mod.resize(surface.points.size());
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"),
      rgb(cloud, "rgb"), sz(cloud, "sigma_z"), ch(cloud, "change"), lod(cloud, "lod");
  for (const dense::EpochPoint& p : surface.points) {
    *x = static_cast<float>(p.x_in_site.x());
    *y = static_cast<float>(p.x_in_site.y());
    *z = static_cast<float>(p.x_in_site.z());
    const uint32_t packed =
        (uint32_t(p.bgr[2]) << 16) | (uint32_t(p.bgr[1]) << 8) | uint32_t(p.bgr[0]);
    std::memcpy(&*rgb, &packed, sizeof packed);
    *sz = p.sigma_z;
    *ch = *lod = std::numeric_limits<float>::quiet_NaN();
    int row, col;
    if (change && change->change.CellOf(p.x_in_site.x(), p.x_in_site.y(), &row, &col)) {
      *ch = change->change.At(dense::kChange, row, col);
      *lod = change->change.At(dense::kLodBand, row, col);
    }
    ++x, ++y, ++z, ++rgb, ++sz, ++ch, ++lod;
  }
  return cloud;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
