// What a site file (io::SiteFile, doc/sites.md) sets for the adjustment, for
// the bundle adjuster nodelet and for offline tools alike.
#pragma once

#include <map>
#include <string>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/io/site_file.h"

namespace slope_monitor {
namespace adjustment {

// A site that lists cameras decides which are UAV cameras by their kind
// (collector and scene options' uav_cameras); returns each listed camera's
// pixel size [mm/px] (those that give one).
std::map<std::string, double> ApplySite(const io::SiteFile& site, EpochCollectorOptions* collector,
                                        BuildSceneOptions* scene);

}  // namespace adjustment
}  // namespace slope_monitor
