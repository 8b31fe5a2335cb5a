#include "slope_monitor/ros/resect_service.h"

#include <cmath>
#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

std::vector<io::PickedPoint> PickedPoints(const slope_monitor::ResectCamera::Request& r) {
  const size_t n = r.points.size();
  if (r.u.size() != n || r.v.size() != n || (!r.ids.empty() && r.ids.size() != n))
    throw InvalidArgument(Message("resect_camera: points (", n, "), u (", r.u.size(), "), v (",
                                  r.v.size(), ") and ids (", r.ids.size(),
                                  ", or empty) must have the same length"));
  std::vector<io::PickedPoint> points(n);
  for (size_t i = 0; i < n; ++i) {
    io::PickedPoint& p = points[i];
    p.id = r.ids.empty() ? "#" + std::to_string(i + 1) : r.ids[i];
    p.xyz = Eigen::Vector3d(r.points[i].x, r.points[i].y, r.points[i].z);
    p.pixel = Eigen::Vector2d(r.u[i], r.v[i]);
    p.line = static_cast<int>(i + 1);
    if (!p.xyz.allFinite() || !p.pixel.allFinite())
      throw InvalidArgument(Message("resect_camera: point ", i, " ('", p.id, "') is not finite"));
  }
  return points;
}

adjustment::ResectCameraOptions Options(const slope_monitor::ResectCamera::Request& r) {
  adjustment::ResectCameraOptions o;
  if (!r.free.empty()) o.free_interior = r.free;
  if (r.pixel_sigma != 0.0) o.pixel_sigma = r.pixel_sigma;
  o.has_position = r.has_position;
  o.position = Eigen::Vector3d(r.position.x, r.position.y, r.position.z);
  o.position_sigma = r.position_sigma;
  o.Check();
  return o;
}

void FillCamera(const adjustment::ResectCameraSummary& s, slope_monitor::CameraEstimate* c) {
  const camera::ExteriorOrientation& e = s.exterior;
  c->site_from_optical = ToPose(e.SiteFromOptical());
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) c->pose_covariance[6 * i + j] = s.exterior_covariance(i, j);
  c->theta = e.angles.theta;
  c->phi = e.angles.phi;
  c->kappa = e.angles.kappa;
  const auto& in = s.model.interior();
  c->principal_distance = in[camera::kC];
  c->x0 = in[camera::kX0];
  c->y0 = in[camera::kY0];
  c->distortion.assign(in.begin() + camera::kK1, in.end());
  c->interior_sigma.assign(camera::kNumInterior, 0.0);  // 0: held
  for (const adjustment::EstimatedParameter& p : s.parameters)
    for (int k = 0; k < camera::kNumInterior; ++k)
      if (p.name == camera::InteriorNames()[k]) c->interior_sigma[k] = p.sigma;
  c->num_observations = static_cast<uint32_t>(2 * s.points.size());
  c->rms_residual_px = s.rms_px;
}

}  // namespace

void Resect(const slope_monitor::ResectCamera::Request& request,
            slope_monitor::ResectCamera::Response* response) {
  *response = slope_monitor::ResectCamera::Response();
  try {
    const camera::CameraModel nominal = capture::CheckCameraInfo(
        FromMsg(request.camera_info), 1.0, 0, 0, "resect_camera: camera_info");
    const adjustment::ResectCameraSummary s =
        adjustment::ResectCamera(PickedPoints(request), nominal, Options(request));
    response->success = s.success;
    response->message = s.success ? s.start : s.message;
    if (!s.success) return;
    FillCamera(s, &response->camera);
    response->camera_info = ToMsg(s.model.ToCameraInfo());
    response->rms_px = s.rms_px;
    for (const adjustment::ResectedPoint& p : s.points) {
      response->residual_u.push_back(p.residual.x());
      response->residual_v.push_back(p.residual.y());
      if (p.snooping_failed) response->snooping_failed.push_back(p.id);
    }
    response->correlation_warnings = s.correlation_warnings;
  } catch (const Error& e) {
    response->success = false;
    response->message = e.what();
  }
}

}  // namespace ros_adapters
}  // namespace slope_monitor
