// Surveyed points as surveyors deliver them: CSV in a national grid, UTM,
// WGS 84 or the site frame, turned into `site` coordinates by PROJ.
//
// File format (comma separated, one point per line):
//   # crs: EPSG:6677                      first line: the CRS of x, y, z:
//                                         "site", "WGS 84" (x lon, y lat [deg],
//                                         z ellipsoidal height [m]) or any CRS
//                                         PROJ knows ("EPSG:NNNN", a PROJ string)
//   id,role,x,y,z,sigma_h,sigma_v         second line: exactly these columns
//   tag36h11/3,control,-21062.634,-11069.549,123.0,0.01,0.02
//   ...
// id: "<family>/<number>" (tag36h11/3, circle/12) or a number (the family is
// then the caller's default_family). role: control | monitoring | check.
// x, y: easting, northing (or lon, lat) whatever the CRS's official axis
// order; z: height as given (see site_crs.h on heights). sigma_h, sigma_v:
// [m] survey standard deviations. Blank lines and lines starting with '#'
// after the header are skipped.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {

struct SurveyedPoint {
  std::string family;
  int id = 0;
  TargetRole role = TargetRole::kControl;
  Eigen::Vector3d position_in_site = Eigen::Vector3d::Zero();  // [m]
  Eigen::Vector2d sigma{0.01, 0.01};                           // [m] horizontal, vertical
  std::string name;  // the survey's own name (a gcp list's gcp_name); "": none
};

// Throws ConfigError naming the file (context), line and column.
std::vector<SurveyedPoint> ReadTargetCsv(const std::string& path, const SiteCrs& site,
                                         const std::string& default_family = "tag36h11");
std::vector<SurveyedPoint> ParseTargetCsv(const std::string& text, const std::string& context,
                                          const SiteCrs& site,
                                          const std::string& default_family = "tag36h11");

// A point given in `crs` ("site", "WGS 84" or a CRS PROJ knows) <-> site.
Eigen::Vector3d SiteFromListCrs(const SiteCrs& site, const std::string& crs,
                                const Eigen::Vector3d& x_in_crs);
Eigen::Vector3d ListCrsFromSite(const SiteCrs& site, const std::string& crs,
                                const Eigen::Vector3d& x_in_site);

// Sets position and sigma of every listed target in `list` (a target not in
// the list yet is added with `size` [m]).
void ApplySurveyedPoints(const std::vector<SurveyedPoint>& points, double size, TargetList* list);

}  // namespace io
}  // namespace slope_monitor
