// Deformation reports: CSV and GeoJSON of the monitoring points, a GeoTIFF of
// the displacement field interpolated over the body, and PNG plots (a
// displacement map with arrows coloured by alert level and a scale bar;
// a time series per point with the alert thresholds).
//
// Every file is written atomically by io::WriteFileAtomically (an exclusive
// mkstemp temporary in the same folder, fsync, rename over <name>), so a
// reader never sees a half-written report and a link planted in the folder is
// never followed. Errors throw IoError naming the file.
//
// CSV columns (one row per point, header line first):
//   id, x, y, z                      [m] reference position (site)
//   lon, lat, h                      [deg, deg, m] WGS 84 (empty without a geodetic origin)
//   time_utc                         ISO 8601 UTC time of the snapshot
//   dx_mm, dy_mm, dz_mm, d_mm        displacement and its magnitude
//   sigma_dx_mm, sigma_dy_mm, sigma_dz_mm  1-sigma
//   vx, vy, vz, speed, sigma_speed   [mm/day]
//   alert                            none | watch | warning | alarm
//   forecast_valid (0/1), forecast_failure_time_utc (ISO 8601), forecast_sigma_h, forecast_window_h
//   sources                          "target+radio", ...
//   sources_disagree                 0 | 1
//   reason                           alert reason and disagreements (quoted)
//
// GeoJSON (RFC 7946: WGS 84 longitude, latitude [deg], ellipsoidal height
// [m], computed by PROJ, common/site_crs.h; no member beyond "type" and
// "features"), split by geometry type and written only for a georeferenced
// site (WriteGeoJson throws InvalidArgument without one; WriteReports skips
// it): <base>.geojson, a FeatureCollection of Point features, one per
// point, with flat properties, one number or word each, named like the CSV
// columns (id, time_utc, reference_epoch, dx_mm ... d_mm, sigma_dx_mm ...,
// vx_mm_per_day ..., speed_mm_per_day, sigma_speed_mm_per_day, alert,
// alert_level 0-3, alert_reason, sources, sources_disagree 0/1,
// forecast_valid 0/1 and, when valid, forecast_failure_time_utc,
// forecast_sigma_h, forecast_window_h, forecast_alpha, else
// forecast_reason); <base>_areas.geojson, a FeatureCollection of the latest
// areas of significant surface change (Snapshot::areas) as Polygon features
// (exterior ring counter-clockwise, holes clockwise; "kind": "change_area",
// id, epoch, time_utc, sign, area_m2, volume_m3, mean_change_m,
// max_change_m, growth_m2, alert, alert_level, alert_reason), empty without
// areas.
//
// The map CRS of the GeoTIFF and the GeoPackage (SiteCrs::MapCrs): a
// shifted_crs site's CRS itself, or for a local_enu site WGS 84 / UTM of the
// origin's zone, written as its EPSG code; without a georeference the local
// engineering CRS "site" (site metres). See doc/coordinates.md.
//
// GeoTIFF: a north-up grid in the map CRS; each cell centre is taken to the
// site frame by PROJ (at the origin's height) and the field interpolated
// there; dx, dy, dz and vx, vy, vz stay site-frame components (true east,
// north, up; in a UTM grid, grid north differs from true north by the
// meridian convergence). Cells farther than grid_margin outside the points'
// convex hull are nodata.
//
// GeoPackage (OGR): layer "points" (id, reference position) and layer
// "latest_displacement" (the CSV's numbers per point, times as DateTime
// fields in UTC), both Point layers in the map CRS (z: the map CRS's height,
// WGS 84 ellipsoidal for UTM), and layer "change_polygons" (Polygon, same
// CRS, vertices at the origin's height: the latest areas of significant
// surface change, Snapshot::areas, with area_id, epoch, time_utc (DateTime),
// sign, area_m2, volume_m3, mean_change_m, max_change_m, growth_m2, alert,
// alert_level, alert_reason; empty without areas).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace deformation {

struct ReportOptions {
  std::optional<Eigen::Vector3d> geodetic_origin;  // [deg, deg, m] lat, lon, h of the site origin
  // The site file's CRS and frame (deformation/site_options.h sets it for a
  // shifted_crs site; it takes precedence over geodetic_origin). With a
  // shifted CRS the GeoTIFF and the GeoPackage are written in that CRS (site
  // coordinates plus the origin), e.g. UTM or a national grid.
  std::optional<SiteCrsOptions> site_crs;
  double grid_resolution = 1.0;  // [m] GeoTIFF cell size
  double grid_margin = 10.0;     // [m] grid extends this far beyond the points
  double idw_power = 2.0;        // [-] inverse-distance weighting exponent
  double idw_radius = 50.0;      // [m] cells farther than this from every point are nodata
  int map_width = 1200;          // [px] displacement map width (height follows the extent)
  int series_width = 1000;       // [px] time series plot size
  int series_height = 600;       // [px]
  double arrow_scale = 0.0;      // [m of map per m of displacement]; 0: chosen so the largest arrow
                                 // spans 15 % of the map
  void Check() const;
};

// The reports' georeference: the site CRS (site_crs), else local ENU at
// geodetic_origin, else none (reports in the local frame `site`).
std::optional<SiteCrs> ReportSiteCrs(const ReportOptions& options);
// The largest displacement of the field in metres per pixel etc. is not
// needed by callers; each writer returns the path it wrote.
std::string WriteCsv(const Snapshot& snapshot, const std::string& path);  // lon, lat empty
std::string WriteCsv(const Snapshot& snapshot, const std::string& path,
                     const ReportOptions& options);
std::string WriteGeoPackage(const Snapshot& snapshot, const std::string& path,
                            const ReportOptions& options);
std::string WriteGeoJson(const Snapshot& snapshot, const std::string& path,
                         const ReportOptions& options);  // the points
std::string WriteAreasGeoJson(const Snapshot& snapshot, const std::string& path,
                              const ReportOptions& options);  // the change areas
// Displacement magnitude [m] (band 1), dx, dy, dz [m] (bands 2-4) and the
// velocity components vx, vy, vz [mm/day] (bands 5-7), float32, each
// interpolated from the points by inverse distance; north-up grid in the map
// CRS (above), nodata NaN.
std::string WriteDisplacementGeoTiff(const Snapshot& snapshot, const std::string& path,
                                     const ReportOptions& options);
std::string WriteDisplacementMap(const Snapshot& snapshot, const std::string& path,
                                 const ReportOptions& options);
// One plot: |d| [mm] (top) and speed [mm/day] with the point's thresholds (bottom).
std::string WriteTimeSeries(const std::string& point_id, const std::vector<SeriesSample>& series,
                            const Thresholds& thresholds, const std::string& path,
                            const ReportOptions& options);

// Writes every requested format ("csv", "geojson", "geotiff", "gpkg", "png"; empty:
// all) into root/subfolder and returns the files written. `root` is the
// configured report folder (created if absent); `subfolder` ("" = the root)
// comes from a request and must stay inside it (io::ResolveSubfolder: no
// "..", no absolute path, no link, no control character; InvalidArgument
// says why). A time series is named after its point id, cut to
// io::kMaxIdLength characters.
std::vector<std::string> WriteReports(const Estimator& estimator, const std::string& root,
                                      const std::string& subfolder,
                                      const std::vector<std::string>& formats,
                                      const ReportOptions& options);

// ENU (site, metres) -> WGS 84 [lon, lat, h] for the given origin [lat, lon, h].
Eigen::Vector3d SiteToGeodetic(const Eigen::Vector3d& x_in_site, const Eigen::Vector3d& origin);

}  // namespace deformation
}  // namespace slope_monitor
