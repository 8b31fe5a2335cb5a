// The pose file resect_camera writes (PREFIX.pose.yaml) and track_camera, the
// targetless_camera nodelet and process_bag read: the reference photo's
// exterior orientation in `site`.
//
//   position: [X0, Y0, Z0]                               # [m]
//   angles_deg: {theta: t, phi: p, kappa: k}             # [deg] camera_model.h convention
//   (other keys: the quaternion and covariance, not read here)
#pragma once

#include <string>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace io {

// Throws IoError (unreadable) or InvalidArgument (missing / malformed keys)
// naming `what` (e.g. "--camera" or "cameras[1].pose_file") and the file.
camera::ExteriorOrientation ReadCameraPoseFile(const std::string& path, const std::string& what);

}  // namespace io
}  // namespace slope_monitor
