// The topics of a moving (UAV) camera in the graph, written once: its photos
// GNSS priors and picked points from the driver, its tie points from the hex_matcher (mode
// sequence). Used by the hex_matcher and bundle adjuster parameters with a
// site file and by process_bag. And the one rule that names a camera by its
// driver's namespace (camera_capture's EpochMarker.source).
#pragma once

#include <string>

namespace slope_monitor {
namespace ros_adapters {

struct UavTopics {
  std::string image;       // /<camera>/camera/image_raw
  std::string prior;       // /<camera>/camera/position_prior
  std::string tie_points;  // /<camera>/tie_points
  // Points picked in the photos (a site's gcp list), TargetObservationArray
  // per photo from camera_capture: /<camera>/camera/picks
  std::string picks;
};

inline UavTopics UavCameraTopics(const std::string& camera) {
  return {"/" + camera + "/camera/image_raw", "/" + camera + "/camera/position_prior",
          "/" + camera + "/tie_points", "/" + camera + "/camera/picks"};
}

// A camera's name (the site file's cameras[].name, EpochMarker.source, the
// <camera> of the topics above) from its driver's namespace: the graph's
// camera topics are /<camera>/camera/..., so camera_capture.launch
// ns:=uav/camera (node namespace "/uav/camera") is camera "uav". A namespace
// that does not end in /camera is the name itself without its slashes
// ("/cam1" -> "cam1").
inline std::string CameraOfNamespace(std::string ns) {
  while (!ns.empty() && ns.back() == '/') ns.pop_back();
  const std::string suffix = "/camera";
  if (ns.size() > suffix.size() &&
      ns.compare(ns.size() - suffix.size(), suffix.size(), suffix) == 0)
    ns.resize(ns.size() - suffix.size());
  while (!ns.empty() && ns.front() == '/') ns.erase(0, 1);
  return ns;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
