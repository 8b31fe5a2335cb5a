// What a site file (io::SiteFile, doc/sites.md) sets in the deformation
// estimator's options, for the nodelet and for offline tools alike.
#pragma once

#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/report.h"
#include "slope_monitor/core/io/site_file.h"

namespace slope_monitor {
namespace deformation {

// The site's thresholds (speeds and area growth) override those in
// `options` (absent ones are kept),
// its aliases are added, and a local_enu site without a geodetic origin in
// `report` gives it one (the origin as WGS 84 latitude, longitude, height).
void ApplySite(const io::SiteFile& site, EstimatorOptions* options, ReportOptions* report);

}  // namespace deformation
}  // namespace slope_monitor
