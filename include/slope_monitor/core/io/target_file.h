// A target list file, whichever of the two formats a crew has: the package's
// YAML (io::TargetList) or a surveyors' CSV (target_csv.h: a '# crs: ...'
// line, then id,role,x,y,z,sigma_h,sigma_v; doc/your_own_site.md). The one
// reader behind a site file's targets.file, the graph's target_list
// parameter and process_bag's --target-list (issue 38: a CSV given there was
// refused as "YAML file '…csv' must hold a map").
#pragma once

#include <string>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {

// The size [m] of a target that a CSV or an inline list introduces (their
// rows carry none): doc/sites.md's targets.size default.
constexpr double kDefaultTargetSize = 1.0;

// `path` ending in ".csv" (any case): the CSV, its coordinates turned into
// the site frame of `site` (null: no site known, and then the CSV must be in
// '# crs: site'), each target `size` [m]; any other name: the YAML list.
// Throws ConfigError naming the file (and line, key or CRS).
TargetList LoadTargetFile(const std::string& path, const SiteCrs* site,
                          double size = kDefaultTargetSize);
// The same, the site given by its CRS options (a SiteFile's `crs`; null: no site).
TargetList LoadTargetFileInSite(const std::string& path, const SiteCrsOptions* site_crs,
                                double size = kDefaultTargetSize);

}  // namespace io
}  // namespace slope_monitor
