#include "slope_monitor/core/capture/geodesy.h"

#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

// Earth-fixed coordinates written out here (independent of PROJ, which the
// conversion uses).
Eigen::Vector3d Ecef(const Geodetic& g) {
  const double e2 = kWgs84F * (2.0 - kWgs84F);
  const double lat = g.latitude_deg * M_PI / 180.0, lon = g.longitude_deg * M_PI / 180.0,
               s = std::sin(lat);
  const double n = kWgs84A / std::sqrt(1.0 - e2 * s * s);
  return Eigen::Vector3d((n + g.height_m) * std::cos(lat) * std::cos(lon),
                         (n + g.height_m) * std::cos(lat) * std::sin(lon),
                         (n * (1.0 - e2) + g.height_m) * s);
}

TEST(Geodesy, RoundTripEverywhere) {
  for (double lat : {-89.9, -45.0, 0.0, 35.6, 60.0, 89.99}) {
    for (double lon : {-179.0, -30.0, 0.0, 139.7}) {
      const LocalTangentPlane ltp({lat, lon, 100.0});
      for (const Eigen::Vector3d& p :
           {Eigen::Vector3d(10.0, -20.0, 3.0), Eigen::Vector3d(-3000.0, 2500.0, 29000.0)}) {
        const Geodetic g = ltp.ToGeodetic(p);
        // PROJ's closed-form inverse of +proj=cart: ~10 um at 29 km above the origin.
        EXPECT_LT((ltp.ToSite(g) - p).norm(), p.z() > 1000.0 ? 1e-4 : 1e-6) << lat << " " << lon;
      }
    }
  }
}

TEST(Geodesy, EnuAxesAtTheOrigin) {
  const LocalTangentPlane ltp({0.0, 0.0, 0.0});
  // Straight up: (0, 0, 100).
  Eigen::Vector3d x = ltp.ToSite({0.0, 0.0, 100.0});
  EXPECT_NEAR(x.x(), 0.0, 1e-6);
  EXPECT_NEAR(x.y(), 0.0, 1e-6);
  EXPECT_NEAR(x.z(), 100.0, 1e-6);
  // 0.01 deg east on the equator: east = a sin(d), up = a (cos(d) - 1).
  const double d = 0.01 * M_PI / 180.0;
  x = ltp.ToSite({0.0, 0.01, 0.0});
  EXPECT_NEAR(x.x(), kWgs84A * std::sin(d), 1e-6);
  EXPECT_NEAR(x.y(), 0.0, 1e-6);
  EXPECT_NEAR(x.z(), kWgs84A * (std::cos(d) - 1.0), 1e-6);
  // North at the equator: ENU north = ECEF z.
  x = ltp.ToSite({0.01, 0.0, 0.0});
  EXPECT_GT(x.y(), 1100.0);  // 0.01 deg of latitude is ~1105.7 m at the equator
  EXPECT_LT(x.y(), 1110.0);
  EXPECT_NEAR(x.x(), 0.0, 1e-6);
}

TEST(Geodesy, SiteRoundTripAndDistances) {
  const LocalTangentPlane ltp({35.36, 138.73, 1200.0});
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(120.5, -80.25, 35.0),
                                   Eigen::Vector3d(-2000.0, 1500.0, -300.0)}) {
    const Geodetic g = ltp.ToGeodetic(p);
    EXPECT_LT((ltp.ToSite(g) - p).norm(), 1e-6);
  }
  // Distances in site equal ECEF distances (rigid transform).
  const Geodetic a{35.361, 138.731, 1210.0}, b{35.358, 138.735, 1190.0};
  EXPECT_NEAR((ltp.ToSite(a) - ltp.ToSite(b)).norm(), (Ecef(a) - Ecef(b)).norm(), 1e-6);
  // At the origin the local ENU covariance is already in site axes.
  Eigen::Matrix3d cov = Eigen::Vector3d(1.0, 4.0, 9.0).asDiagonal();
  EXPECT_LT((ltp.CovarianceToSite(ltp.origin(), cov) - cov).norm(), 1e-12);
  // 1 km away it stays symmetric with the same trace.
  const Eigen::Matrix3d c2 = ltp.CovarianceToSite({35.37, 138.74, 1200.0}, cov);
  EXPECT_NEAR(c2.trace(), 14.0, 1e-9);
  EXPECT_LT((c2 - c2.transpose()).norm(), 1e-12);
}

TEST(Geodesy, InvalidOriginNamesTheValue) {
  try {
    LocalTangentPlane ltp({95.0, 0.0, 0.0});
    FAIL() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("latitude 95"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LocalTangentPlane({0.0, 200.0, 0.0}), InvalidArgument);
  EXPECT_THROW(LocalTangentPlane({0.0, 0.0, NAN}), InvalidArgument);
}

// A shifted_crs site in UTM zone 31N (central meridian 3 E) with its origin
// at (500 000, 0): on the central meridian the grid is the local ENU scaled
// by k0 = 0.9996; 0.001 deg of latitude at the equator is a(1 - e^2) * pi /
// 180 / 1000 = 110.574 m of meridian, 110.530 m of grid. At 45 N, 2.9 deg
// east of the central meridian, true north points toward the central
// meridian, west of grid north by the meridian convergence atan(tan(2.9 deg)
// sin(45 deg)) = 2.051 deg (a heading of 10 deg true is 7.949 deg from grid
// north); the local tangent plane
// leaves headings as they are. The covariance scales by the grid's scale at
// the photo's height.
TEST(Geodesy, SiteFrameOfAShiftedUtmSite) {
  SiteCrsOptions utm;
  utm.crs = "EPSG:32631";
  utm.origin = Eigen::Vector3d(500000.0, 0.0, 0.0);
  utm.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteFrame frame(utm);
  const Eigen::Vector3d x = frame.ToSite({0.001, 3.0, 100.0});
  EXPECT_NEAR(x.x(), 0.0, 1e-6);
  EXPECT_NEAR(x.y(), 110.574 * 0.9996, 2e-3);
  EXPECT_NEAR(x.z(), 100.0, 1e-6);
  const Eigen::Matrix3d cov =
      frame.CovarianceToSite({0.001, 3.0, 100.0}, Eigen::Vector3d(4.0, 4.0, 9.0).asDiagonal());
  // 1 m at 100 m above the ellipsoid is a / (a + 100) m on it east (the prime
  // vertical radius at the equator is a), M / (M + 100) north (M = a (1 - e^2)).
  const double e2 = kWgs84F * (2.0 - kWgs84F), m = kWgs84A * (1.0 - e2);
  const double k_east = 0.9996 * kWgs84A / (kWgs84A + 100.0), k_north = 0.9996 * m / (m + 100.0);
  EXPECT_NEAR(cov(0, 0), 4.0 * k_east * k_east, 1e-5);
  EXPECT_NEAR(cov(1, 1), 4.0 * k_north * k_north, 1e-5);
  EXPECT_NEAR(cov(2, 2), 9.0, 1e-6);
  EXPECT_NEAR(cov(0, 1), 0.0, 1e-6);
  const double convergence =
      std::atan(std::tan(2.9 * M_PI / 180.0) * std::sin(M_PI / 4.0)) * 180.0 / M_PI;
  EXPECT_NEAR(frame.HeadingToSite({45.0, 5.9, 300.0}, 10.0), 10.0 - convergence, 0.01);
  EXPECT_NEAR(frame.HeadingToSite({45.0, 3.0, 300.0}, 10.0), 10.0, 1e-6);
  const SiteFrame plane(Geodetic{45.0, 5.9, 300.0});
  EXPECT_EQ(plane.HeadingToSite({45.0, 5.9, 300.0}, 10.0), 10.0);
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
