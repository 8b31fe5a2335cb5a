// Geodetic (WGS84) <-> local `site` frame conversion, by PROJ.
//
// `site` is a local tangent plane: x east, y north, z up (ENU), with its
// origin at a geodetic point (latitude, longitude in degrees, height above
// the WGS84 ellipsoid in metres). This is SiteCrs (common/site_crs.h) with
// a WGS 84 origin, in the latitude-first form camera_capture and the
// simulator use; the conversion itself is PROJ's (no flat-earth
// approximation).
//
// Used by camera_capture (GNSS fix -> position prior in site) and by the
// simulator (site -> NavSatFix):
//
//   capture::LocalTangentPlane ltp({35.0, 139.0, 100.0});   // site.origin
//   Eigen::Vector3d x_in_site = ltp.ToSite({35.001, 139.002, 120.0});
//   capture::Geodetic g = ltp.ToGeodetic(x_in_site);
//
// Note on heights: NavSatFix.altitude and these heights are ellipsoidal; EXIF
// GPSAltitude is usually above mean sea level (add the geoid height N to get
// the ellipsoidal height: h = H_msl + N).
#pragma once

#include <memory>

#include <Eigen/Core>

#include "slope_monitor/core/common/site_crs.h"

namespace slope_monitor {
namespace capture {

// WGS84 ellipsoid.
constexpr double kWgs84A = 6378137.0;            // semi-major axis [m]
constexpr double kWgs84F = 1.0 / 298.257223563;  // flattening [-]

struct Geodetic {
  double latitude_deg = 0.0;   // [deg], north positive, [-90, 90]
  double longitude_deg = 0.0;  // [deg], east positive, [-180, 180]
  double height_m = 0.0;       // [m] above the WGS84 ellipsoid
};

// Throws InvalidArgument naming the value when latitude/longitude are out of
// range or any value is not finite.
void CheckGeodetic(const Geodetic& g, const char* what);

class LocalTangentPlane {
 public:
  // Throws InvalidArgument for an invalid origin.
  explicit LocalTangentPlane(const Geodetic& origin);

  const Geodetic& origin() const { return origin_; }
  // Geodetic point -> site (ENU) coordinates [m].
  Eigen::Vector3d ToSite(const Geodetic& g) const;
  // Site (ENU) coordinates [m] -> geodetic point.
  Geodetic ToGeodetic(const Eigen::Vector3d& x_in_site) const;
  // Rotates a covariance given in the ENU axes at point g (e.g. a
  // NavSatFix position_covariance) into the site axes. For points within a few
  // km of the origin this is close to the identity rotation.
  Eigen::Matrix3d CovarianceToSite(const Geodetic& g,
                                   const Eigen::Matrix3d& cov_in_local_enu) const;

 private:
  Geodetic origin_;
  std::shared_ptr<const SiteCrs> site_;
};

// A site file's frame for GNSS positions (camera_capture's position priors):
// a local tangent plane at a WGS 84 origin (as LocalTangentPlane), or any
// site frame of a site file, e.g. shifted_crs (UTM coordinates minus the
// origin), through PROJ. Covariances and headings given in the local
// east-north-up axes of a point are turned into the site's axes; in a
// projected CRS these differ by the meridian convergence (up to ~3 deg at a
// UTM zone's edge) and the scale factor.
class SiteFrame {
 public:
  explicit SiteFrame(const Geodetic& local_enu_origin);  // throws InvalidArgument
  explicit SiteFrame(const SiteCrsOptions& crs);  // throws ConfigError (SiteCrs) naming the CRS

  Eigen::Vector3d ToSite(const Geodetic& g) const;
  // A covariance in the ENU axes at g (e.g. NavSatFix.position_covariance).
  Eigen::Matrix3d CovarianceToSite(const Geodetic& g,
                                   const Eigen::Matrix3d& cov_in_local_enu) const;
  // A heading at g [deg, clockwise from true north] as clockwise from the
  // site's +y axis (a local tangent plane: unchanged, as its site axes).
  double HeadingToSite(const Geodetic& g, double heading_deg) const;

 private:
  Eigen::Matrix3d SiteFromLocalEnu(const Geodetic& g) const;  // the local Jacobian
  std::shared_ptr<const LocalTangentPlane> plane_;            // local_enu at a WGS 84 origin
  std::shared_ptr<const SiteCrs> crs_;                        // else
};

}  // namespace capture
}  // namespace slope_monitor
