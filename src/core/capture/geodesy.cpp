#include "slope_monitor/core/capture/geodesy.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

// The axes (not a position conversion) of the local east-north-up frame at a
// geodetic point, as rows in earth-fixed (ECEF) axes.
Eigen::Matrix3d EnuAxes(double latitude_deg, double longitude_deg) {
  const double lat = latitude_deg * M_PI / 180.0;
  const double lon = longitude_deg * M_PI / 180.0;
  const double sl = std::sin(lat), cl = std::cos(lat), so = std::sin(lon), co = std::cos(lon);
  Eigen::Matrix3d r;
  r << -so, co, 0.0,           // east
      -sl * co, -sl * so, cl,  // north
      cl * co, cl * so, sl;    // up
  return r;
}

}  // namespace

void CheckGeodetic(const Geodetic& g, const char* what) {
  if (!std::isfinite(g.latitude_deg) || std::abs(g.latitude_deg) > 90.0) {
    throw InvalidArgument(Message(what, " latitude ", g.latitude_deg, " deg is outside [-90, 90]"));
  }
  if (!std::isfinite(g.longitude_deg) || std::abs(g.longitude_deg) > 180.0) {
    throw InvalidArgument(
        Message(what, " longitude ", g.longitude_deg, " deg is outside [-180, 180]"));
  }
  if (!std::isfinite(g.height_m) || std::abs(g.height_m) > 1e5) {
    throw InvalidArgument(Message(what, " height ", g.height_m, " m is outside [-1e5, 1e5]"));
  }
}

LocalTangentPlane::LocalTangentPlane(const Geodetic& origin) : origin_(origin) {
  CheckGeodetic(origin, "site origin");
  site_ = std::make_shared<const SiteCrs>(
      SiteCrs::LocalEnuAtWgs84(origin.latitude_deg, origin.longitude_deg, origin.height_m));
}

Eigen::Vector3d LocalTangentPlane::ToSite(const Geodetic& g) const {
  return site_->SiteFromWgs84(Eigen::Vector3d(g.longitude_deg, g.latitude_deg, g.height_m));
}

Geodetic LocalTangentPlane::ToGeodetic(const Eigen::Vector3d& x_in_site) const {
  const Eigen::Vector3d lon_lat_h = site_->Wgs84FromSite(x_in_site);
  return Geodetic{lon_lat_h.y(), lon_lat_h.x(), lon_lat_h.z()};
}

Eigen::Matrix3d LocalTangentPlane::CovarianceToSite(const Geodetic& g,
                                                    const Eigen::Matrix3d& cov) const {
  const Eigen::Matrix3d site_from_local = EnuAxes(origin_.latitude_deg, origin_.longitude_deg) *
                                          EnuAxes(g.latitude_deg, g.longitude_deg).transpose();
  return site_from_local * cov * site_from_local.transpose();
}

SiteFrame::SiteFrame(const Geodetic& local_enu_origin)
    : plane_(std::make_shared<const LocalTangentPlane>(local_enu_origin)) {}

SiteFrame::SiteFrame(const SiteCrsOptions& crs) : crs_(std::make_shared<const SiteCrs>(crs)) {}

Eigen::Vector3d SiteFrame::ToSite(const Geodetic& g) const {
  if (plane_) return plane_->ToSite(g);
  return crs_->SiteFromWgs84(Eigen::Vector3d(g.longitude_deg, g.latitude_deg, g.height_m));
}

// Columns: the site vectors of 1 m east, north and up at g (PROJ's
// conversion differenced; its curvature over 1 m is below 1e-7 m).
Eigen::Matrix3d SiteFrame::SiteFromLocalEnu(const Geodetic& g) const {
  const LocalTangentPlane at(g);
  const Eigen::Vector3d x = ToSite(g);
  Eigen::Matrix3d j;
  for (int k = 0; k < 3; ++k) j.col(k) = ToSite(at.ToGeodetic(Eigen::Vector3d::Unit(k))) - x;
  return j;
}

Eigen::Matrix3d SiteFrame::CovarianceToSite(const Geodetic& g, const Eigen::Matrix3d& cov) const {
  if (plane_) return plane_->CovarianceToSite(g, cov);
  const Eigen::Matrix3d j = SiteFromLocalEnu(g);
  return j * cov * j.transpose();
}

double SiteFrame::HeadingToSite(const Geodetic& g, double heading_deg) const {
  if (plane_) return heading_deg;
  const Eigen::Vector3d north = SiteFromLocalEnu(g).col(1);
  return heading_deg + std::atan2(north.x(), north.y()) * 180.0 / M_PI;
}

}  // namespace capture
}  // namespace slope_monitor
