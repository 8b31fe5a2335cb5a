#include "slope_monitor/core/capture/geodesy.h"

#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

constexpr double kB = kWgs84A * (1.0 - kWgs84F);

TEST(Geodesy, EcefOfHandCheckablePoints) {
  // Equator / prime meridian: (a + h, 0, 0).
  Eigen::Vector3d x = GeodeticToEcef({0.0, 0.0, 100.0});
  EXPECT_NEAR(x.x(), kWgs84A + 100.0, 1e-6);
  EXPECT_NEAR(x.y(), 0.0, 1e-6);
  EXPECT_NEAR(x.z(), 0.0, 1e-6);
  // Equator, 90 E: (0, a, 0).
  x = GeodeticToEcef({0.0, 90.0, 0.0});
  EXPECT_NEAR(x.x(), 0.0, 1e-6);
  EXPECT_NEAR(x.y(), kWgs84A, 1e-6);
  // North pole: (0, 0, b + h).
  x = GeodeticToEcef({90.0, 0.0, 10.0});
  EXPECT_NEAR(x.z(), kB + 10.0, 1e-6);
  EXPECT_NEAR(std::hypot(x.x(), x.y()), 0.0, 1e-6);
}

TEST(Geodesy, EcefRoundTrip) {
  for (double lat : {-89.9, -45.0, 0.0, 35.6, 60.0, 89.99}) {
    for (double lon : {-179.0, -30.0, 0.0, 139.7}) {
      for (double h : {-100.0, 0.0, 2500.0, 30000.0}) {
        const Geodetic g = EcefToGeodetic(GeodeticToEcef({lat, lon, h}));
        EXPECT_NEAR(g.latitude_deg, lat, 1e-10) << lat << " " << lon << " " << h;
        EXPECT_NEAR(g.longitude_deg, lon, 1e-10);
        EXPECT_NEAR(g.height_m, h, 1e-6);
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
  EXPECT_NEAR((ltp.ToSite(a) - ltp.ToSite(b)).norm(), (GeodeticToEcef(a) - GeodeticToEcef(b)).norm(), 1e-6);
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

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
