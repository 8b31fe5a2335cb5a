#include "slope_monitor/core/capture/geodesy.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kE2 = kWgs84F * (2.0 - kWgs84F);  // first eccentricity squared
constexpr double kB = kWgs84A * (1.0 - kWgs84F);   // semi-minor axis

}  // namespace

void CheckGeodetic(const Geodetic& g, const char* what) {
  if (!std::isfinite(g.latitude_deg) || std::abs(g.latitude_deg) > 90.0) {
    throw InvalidArgument(Message(what, " latitude ", g.latitude_deg, " deg is outside [-90, 90]"));
  }
  if (!std::isfinite(g.longitude_deg) || std::abs(g.longitude_deg) > 180.0) {
    throw InvalidArgument(Message(what, " longitude ", g.longitude_deg, " deg is outside [-180, 180]"));
  }
  if (!std::isfinite(g.height_m) || std::abs(g.height_m) > 1e5) {
    throw InvalidArgument(Message(what, " height ", g.height_m, " m is outside [-1e5, 1e5]"));
  }
}

Eigen::Vector3d GeodeticToEcef(const Geodetic& g) {
  const double lat = g.latitude_deg * kDegToRad;
  const double lon = g.longitude_deg * kDegToRad;
  const double s = std::sin(lat);
  const double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);  // prime vertical radius
  return Eigen::Vector3d((n + g.height_m) * std::cos(lat) * std::cos(lon),
                         (n + g.height_m) * std::cos(lat) * std::sin(lon),
                         (n * (1.0 - kE2) + g.height_m) * s);
}

Geodetic EcefToGeodetic(const Eigen::Vector3d& x) {
  const double p = std::hypot(x.x(), x.y());
  Geodetic g;
  g.longitude_deg = std::atan2(x.y(), x.x()) / kDegToRad;
  // Bowring's parametric start, then fixed-point iteration on the latitude.
  const double ep2 = kE2 / (1.0 - kE2);
  double beta = std::atan2(x.z() * kWgs84A, p * kB);
  double lat = std::atan2(x.z() + ep2 * kB * std::pow(std::sin(beta), 3),
                          p - kE2 * kWgs84A * std::pow(std::cos(beta), 3));
  for (int i = 0; i < 5; ++i) {
    beta = std::atan2((1.0 - kWgs84F) * std::sin(lat), std::cos(lat));
    lat = std::atan2(x.z() + ep2 * kB * std::pow(std::sin(beta), 3),
                     p - kE2 * kWgs84A * std::pow(std::cos(beta), 3));
  }
  const double s = std::sin(lat);
  const double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
  // Height: stable near the poles and the equator.
  if (std::abs(std::cos(lat)) > 1e-6) {
    g.height_m = p / std::cos(lat) - n;
  } else {
    g.height_m = std::abs(x.z()) - n * (1.0 - kE2);
  }
  g.latitude_deg = lat / kDegToRad;
  return g;
}

Eigen::Matrix3d EnuFromEcefRotation(double latitude_deg, double longitude_deg) {
  const double lat = latitude_deg * kDegToRad;
  const double lon = longitude_deg * kDegToRad;
  const double sl = std::sin(lat), cl = std::cos(lat), so = std::sin(lon), co = std::cos(lon);
  Eigen::Matrix3d r;
  r << -so, co, 0.0,                 // east
      -sl * co, -sl * so, cl,        // north
      cl * co, cl * so, sl;          // up
  return r;
}

LocalTangentPlane::LocalTangentPlane(const Geodetic& origin) : origin_(origin) {
  CheckGeodetic(origin, "site origin");
  origin_in_ecef_ = GeodeticToEcef(origin);
  site_from_ecef_ = EnuFromEcefRotation(origin.latitude_deg, origin.longitude_deg);
}

Eigen::Vector3d LocalTangentPlane::ToSite(const Geodetic& g) const {
  return site_from_ecef_ * (GeodeticToEcef(g) - origin_in_ecef_);
}

Geodetic LocalTangentPlane::ToGeodetic(const Eigen::Vector3d& x_in_site) const {
  return EcefToGeodetic(origin_in_ecef_ + site_from_ecef_.transpose() * x_in_site);
}

Eigen::Matrix3d LocalTangentPlane::CovarianceToSite(const Geodetic& g, const Eigen::Matrix3d& cov) const {
  const Eigen::Matrix3d site_from_local =
      site_from_ecef_ * EnuFromEcefRotation(g.latitude_deg, g.longitude_deg).transpose();
  return site_from_local * cov * site_from_local.transpose();
}

}  // namespace capture
}  // namespace slope_monitor
