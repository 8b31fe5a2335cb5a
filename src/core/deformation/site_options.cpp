#include "slope_monitor/core/deformation/site_options.h"

#include "slope_monitor/core/common/site_crs.h"

namespace slope_monitor {
namespace deformation {
namespace {

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  const size_t b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

}  // namespace

void ApplySite(const io::SiteFile& site, EstimatorOptions* o, ReportOptions* report) {
  const double to_si = site.thresholds.unit == "mm/day" ? 1e-3 / 86400.0 : 1e-3 / 3600.0;
  if (site.thresholds.watch) o->alerts.thresholds.watch = *site.thresholds.watch * to_si;
  if (site.thresholds.warning) o->alerts.thresholds.warning = *site.thresholds.warning * to_si;
  if (site.thresholds.alarm) o->alerts.thresholds.alarm = *site.thresholds.alarm * to_si;
  Thresholds& th = o->alerts.thresholds;
  if (site.thresholds.displacement_watch)
    th.displacement_watch = *site.thresholds.displacement_watch * 1e-3;
  if (site.thresholds.displacement_warning)
    th.displacement_warning = *site.thresholds.displacement_warning * 1e-3;
  if (site.thresholds.displacement_alarm)
    th.displacement_alarm = *site.thresholds.displacement_alarm * 1e-3;
  if (site.thresholds.area_growth_watch) o->areas.growth_watch = *site.thresholds.area_growth_watch;
  if (site.thresholds.area_growth_warning)
    o->areas.growth_warning = *site.thresholds.area_growth_warning;
  for (const std::string& entry :
       site.aliases) {  // "measured_id = monitoring_point_id" (checked by the reader)
    const size_t eq = entry.find('=');
    o->aliases[Trim(entry.substr(0, eq))] = Trim(entry.substr(eq + 1));
  }
  // Reports in the site's CRS: a shifted CRS (UTM, a national grid) is
  // written in that CRS; local ENU as before, from the origin in WGS 84.
  if (site.crs.frame == SiteCrsOptions::Frame::kShiftedCrs) report->site_crs = site.crs;
  if (!report->geodetic_origin && site.crs.frame == SiteCrsOptions::Frame::kLocalEnu) {
    const Eigen::Vector3d lon_lat_h = SiteCrs(site.crs).origin_wgs84();
    report->geodetic_origin = Eigen::Vector3d(lon_lat_h.y(), lon_lat_h.x(), lon_lat_h.z());
  }
}

}  // namespace deformation
}  // namespace slope_monitor
