// The topics of a moving (UAV) camera in the graph, written once: its photos
// and GNSS priors from the driver, its tie points from the hex_matcher (mode
// sequence). Used by the hex_matcher and bundle adjuster parameters with a
// site file and by process_bag.
#pragma once

#include <string>

namespace slope_monitor {
namespace ros_adapters {

struct UavTopics {
  std::string image;       // /<camera>/camera/image_raw
  std::string prior;       // /<camera>/camera/position_prior
  std::string tie_points;  // /<camera>/tie_points
};

inline UavTopics UavCameraTopics(const std::string& camera) {
  return {"/" + camera + "/camera/image_raw", "/" + camera + "/camera/position_prior",
          "/" + camera + "/tie_points"};
}

}  // namespace ros_adapters
}  // namespace slope_monitor
