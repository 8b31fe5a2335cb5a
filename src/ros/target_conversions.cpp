#include "slope_monitor/ros/target_conversions.h"

#include <algorithm>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/rigid3.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/image_limits.h"

namespace slope_monitor {
namespace ros_adapters {

uint8_t TargetRoleToMsg(const std::optional<io::TargetRole>& role) {
  return !role                               ? TargetObservation::ROLE_UNKNOWN
         : *role == io::TargetRole::kControl ? TargetObservation::ROLE_CONTROL
         : *role == io::TargetRole::kCheck   ? TargetObservation::ROLE_CHECK
                                             : TargetObservation::ROLE_MONITORING;
}

CentroidedImage CentroidImage(const targets::TargetCentroider& centroider,
                              const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info,
                              const std::optional<Eigen::Isometry3d>& site_from_optical,
                              const std::string& camera_name, double pixel_size,
                              const std::string& topic) {
  // Size against the pixel budget and the data, before anything converts it.
  try {
    CheckImageMessage(image);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(Message(topic, ": ", e.what()));
  }
  // Encoding, empty image, size against camera_info: named with the topic.
  targets::CheckImageInput(topic, image.width, image.height, image.encoding, info.width,
                           info.height);
  // No tracked object owns the image: a plain (shared-data) conversion.
  cv_bridge::CvImageConstPtr cv_image =
      cv_bridge::toCvShare(image, boost::shared_ptr<void const>());
  std::optional<targets::ViewGeometry> view;
  if (site_from_optical && info.K[0] > 0) {
    const Rigid3 optical_from_site = Rigid3(Eigen::Matrix3d(site_from_optical->rotation()),
                                            Eigen::Vector3d(site_from_optical->translation()))
                                         .Inverse();
    view.emplace();
    view->camera = CameraModelFromCameraInfo(info, pixel_size);
    view->pose = camera::ExteriorOrientation::FromOpticalFromSite(optical_from_site);
  }
  CentroidedImage out;
  out.mono = targets::ToMono(cv_image->image, image.encoding);
  out.result = centroider.DetectMono(out.mono, view ? &*view : nullptr);
  TargetObservationArray& msg = out.targets;
  msg.header = image.header;
  msg.camera_name = camera_name;
  msg.image_width = image.width;
  msg.image_height = image.height;
  for (const auto& o : out.result.observations) {
    TargetObservation m;
    m.id = o.id;
    m.family = o.family;
    m.role = TargetRoleToMsg(o.role);
    m.x = o.centre.x();
    m.y = o.centre.y();
    const auto cov = ToRowMajor<2>(o.covariance);
    std::copy(cov.begin(), cov.end(), m.covariance.begin());
    if (o.has_corners) {
      for (size_t k = 0; k < 4; ++k) {
        m.corners[2 * k] = o.corners[k].x();
        m.corners[2 * k + 1] = o.corners[k].y();
      }
    }
    m.size_px = o.size_px;
    m.quality = o.quality;
    msg.observations.push_back(m);
  }
  msg.rejected = out.result.rejections.size();
  for (const auto& rj : out.result.rejections) {
    msg.reject_reasons.push_back(targets::RejectReasonName(rj.reason) + ": " + rj.family + "/" +
                                 std::to_string(rj.id) + " " + rj.detail);
  }
  return out;
}

sensor_msgs::Image ToDebugImage(const CentroidedImage& c, const std_msgs::Header& header) {
  sensor_msgs::Image out;
  cv_bridge::CvImage(header, sensor_msgs::image_encodings::BGR8,
                     targets::DrawResult(c.mono.mono8, c.result))
      .toImageMsg(out);
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
