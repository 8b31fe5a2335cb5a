#include "slope_monitor/core/adjustment/site_options.h"

namespace slope_monitor {
namespace adjustment {

std::map<std::string, double> ApplySite(const io::SiteFile& site, EpochCollectorOptions* collector,
                                        BuildSceneOptions* scene) {
  std::map<std::string, double> pixel_size;
  if (site.cameras.empty()) return pixel_size;  // the site says nothing about cameras
  std::vector<std::string> uav;
  for (const io::SiteCamera& cam : site.cameras) {
    if (cam.pixel_size > 0.0) pixel_size[cam.name] = cam.pixel_size;
    if (cam.kind == io::CameraKind::kUav) uav.push_back(cam.name);
  }
  collector->uav_cameras = uav;
  scene->uav_cameras = uav;
  return pixel_size;
}

}  // namespace adjustment
}  // namespace slope_monitor
