// A site's coordinate reference system and its local `site` frame, by PROJ.
//
// The site is defined by a CRS (an "EPSG:NNNN" code or a PROJ string; default
// WGS 84 3-D, EPSG:4979) and an origin given in that CRS. The `site` frame
// (x east, y north, z up, metres) is either
//  * kLocalEnu (default): the local east-north-up frame at the origin, on the
//    WGS 84 ellipsoid (PROJ's "topocentric" conversion), or
//  * kShiftedCrs: the CRS's own coordinates minus the origin (a projected CRS
//    such as UTM or JGD2011 zone IX; x easting, y northing, z height).
//
// Axis order: coordinates "in the CRS" are always x = easting / longitude
// [deg], y = northing / latitude [deg], z = height [m], whatever the CRS's
// official axis order (EPSG:6677 officially lists northing first; PROJ's
// normalisation for visualisation is applied). Heights: PROJ applies no geoid
// model to a 2-D CRS, so z is used as given; give the origin's height the same
// way as the points' (both orthometric or both ellipsoidal) and the heights in
// `site` are consistent to the geoid's slope over the site (millimetres over a
// few hundred metres).
//
// All geodesy goes through PROJ: WGS 84 <-> the site CRS by
// proj_create_crs_to_crs (best available operation), and geodetic <-> local
// ENU by "+proj=cart" and "+proj=topocentric". Thread-safe (one PROJ context
// per SiteCrs, calls serialised).
//
//   SiteCrsOptions o;
//   o.crs = "EPSG:32654";                       // UTM zone 54N
//   o.origin = {500000.0, 3985000.0, 100.0};    // in the CRS
//   SiteCrs site(o);                            // local ENU at the origin
//   Eigen::Vector3d x_in_site = site.SiteFromCrs({500100.0, 3985200.0, 120.0});
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>

namespace slope_monitor {

struct SiteCrsOptions {
  enum class Frame { kLocalEnu, kShiftedCrs };
  std::string crs = "EPSG:4979";                     // site CRS: "EPSG:NNNN" or a PROJ string
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // `site` origin in the CRS (x, y, z as above)
  Frame frame = Frame::kLocalEnu;
  // Throws InvalidArgument naming the value: empty CRS, non-finite origin.
  void Check() const;
};

// "local_enu" / "shifted_crs" <-> Frame; throws InvalidArgument for anything else.
SiteCrsOptions::Frame ParseSiteFrame(const std::string& name);

class SiteCrs {
 public:
  // Throws InvalidArgument when PROJ does not know the CRS or cannot convert
  // it to WGS 84 (the message names the CRS and PROJ's reason).
  explicit SiteCrs(const SiteCrsOptions& options);
  // Local ENU at a WGS 84 origin: latitude, longitude [deg], ellipsoidal height [m].
  static SiteCrs LocalEnuAtWgs84(double latitude_deg, double longitude_deg, double height_m);
  ~SiteCrs();
  SiteCrs(SiteCrs&&) noexcept;
  SiteCrs& operator=(SiteCrs&&) noexcept;

  const SiteCrsOptions& options() const;
  // The origin as WGS 84 [lon deg, lat deg, h m].
  const Eigen::Vector3d& origin_wgs84() const;
  // The map CRS of every output a GIS reads (GeoTIFF, GeoPackage): with
  // kShiftedCrs the site CRS itself; with kLocalEnu WGS 84 / UTM, the zone of
  // the origin ("EPSG:326zz" north of the equator, "EPSG:327zz" south; zone
  // floor((lon + 180) / 6) + 1, without the Norway / Svalbard exceptions).
  // Map coordinates are x easting, y northing, z height (kLocalEnu: WGS 84
  // ellipsoidal height; kShiftedCrs: the CRS's z).
  const std::string& MapCrs() const;
  // The map CRS's EPSG code; 0 when it has none (a site CRS given as a PROJ string).
  int MapEpsg() const;
  // The map CRS as WKT (for a CRS without EPSG code).
  std::string CrsWkt() const;
  // site [m] <-> map CRS. kShiftedCrs: plus / minus the origin (exact);
  // kLocalEnu: through WGS 84 by PROJ. Throw InvalidArgument naming the point.
  Eigen::Vector3d MapFromSite(const Eigen::Vector3d& x_in_site) const;
  Eigen::Vector3d SiteFromMap(const Eigen::Vector3d& x_in_map) const;

  // Coordinates in the site CRS <-> site [m]. Throw InvalidArgument naming
  // the point when PROJ cannot convert it.
  Eigen::Vector3d SiteFromCrs(const Eigen::Vector3d& x_in_crs) const;
  Eigen::Vector3d CrsFromSite(const Eigen::Vector3d& x_in_site) const;
  // WGS 84 [lon deg, lat deg, ellipsoidal h m] <-> site [m].
  Eigen::Vector3d SiteFromWgs84(const Eigen::Vector3d& lon_lat_h) const;
  Eigen::Vector3d Wgs84FromSite(const Eigen::Vector3d& x_in_site) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slope_monitor
