#include "slope_monitor/core/io/camera_pose_file.h"

#include <cmath>

#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {

camera::ExteriorOrientation ReadCameraPoseFile(const std::string& path, const std::string& what) {
  constexpr double kRad = M_PI / 180.0;
  YAML::Node n;
  try {
    n = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw IoError(Message(what, ": cannot read '", path, "': ", e.what()));
  }
  const YAML::Node a = n["angles_deg"];
  if (!n["position"] || !n["position"].IsSequence() || n["position"].size() != 3 || !a ||
      !a["theta"] || !a["phi"] || !a["kappa"])
    throw InvalidArgument(Message(
        what, " '", path, "': needs position [X, Y, Z] and angles_deg {theta, phi, kappa}"));
  camera::ExteriorOrientation e;
  try {
    for (int k = 0; k < 3; ++k) e.position(k) = n["position"][k].as<double>();
    e.angles.theta = a["theta"].as<double>() * kRad;
    e.angles.phi = a["phi"].as<double>() * kRad;
    e.angles.kappa = a["kappa"].as<double>() * kRad;
  } catch (const YAML::Exception& ex) {
    throw InvalidArgument(Message(what, " '", path, "': not a number: ", ex.what()));
  }
  if (!e.position.allFinite() || !std::isfinite(e.angles.theta + e.angles.phi + e.angles.kappa))
    throw InvalidArgument(Message(what, " '", path, "': non-finite position or angle"));
  return e;
}

}  // namespace io
}  // namespace slope_monitor
