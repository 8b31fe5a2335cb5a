// A target list file, whichever of the two formats a crew has: the package's
// YAML (io::TargetList) or a surveyors' CSV (target_csv.h: a '# crs: ...'
// line, then id,role,x,y,z,sigma_h,sigma_v; doc/your_own_site.md). The one
// reader behind a site file's targets.file, the graph's target_list
// parameter and process_bag's --target-list (a CSV given there is read as
// CSV, not refused as a YAML file that "must hold a map").
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/gcp_list.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {

// The size [m] of a target that a CSV or an inline list introduces (their
// rows carry none): doc/sites.md's targets.size default.
constexpr double kDefaultTargetSize = 1.0;

// A crew's control points picked in photos, OpenDroneMap's gcp_list.txt
// (gcp_list.h), as targets of family "gcp" (never detected: the picks reach
// the graph from camera_capture, doc/uav_real_flight.md): each point a
// control point with `sigma` [m] horizontal (vertical twice that; 10 m when
// the list has no heights), those named in `check` check points; positions
// turned from the list's CRS into `site`. Throws ConfigError naming the file
// (unreadable, bad line, a check name not in the list).
TargetList LoadGcpTargets(const std::string& path, const SiteCrs& site,
                          const std::vector<std::string>& check = {},
                          double sigma = kDefaultGcpSigma, double size = kDefaultTargetSize);

// Whether `path` names a gcp list (".txt", any case).
bool IsGcpListName(const std::string& path);

// `path` ending in ".csv" (any case): the CSV, its coordinates turned into
// the site frame of `site` (null: no site known, and then the CSV must be in
// '# crs: site'), each target `size` [m]; ending in ".txt": a gcp list
// (LoadGcpTargets with its defaults; it needs the site); any other name: the
// YAML list.
// Throws ConfigError naming the file (and line, key or CRS).
TargetList LoadTargetFile(const std::string& path, const SiteCrs* site,
                          double size = kDefaultTargetSize);
// The same, the site given by its CRS options (a SiteFile's `crs`; null: no site).
TargetList LoadTargetFileInSite(const std::string& path, const SiteCrsOptions* site_crs,
                                double size = kDefaultTargetSize);

}  // namespace io
}  // namespace slope_monitor
