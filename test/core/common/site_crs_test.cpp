// SiteCrs (PROJ) against hand-checkable values: the local ENU frame at a
// point of the equator, where the WGS 84 ellipsoid's equator is a circle of
// radius a and its polar semi-axis is b.
#include "slope_monitor/core/common/site_crs.h"

#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace {

constexpr double kA = 6378137.0;                         // WGS 84 semi-major axis [m]
constexpr double kB = kA * (1.0 - 1.0 / 298.257223563);  // semi-minor axis [m]

TEST(SiteCrs, LocalEnuAtTheEquatorMatchesTheEllipsoidsCircleAndAxis) {
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(0.0, 0.0, 0.0);
  for (double d : {0.001, 0.01, 1.0, 10.0}) {  // [deg] along the equator
    const Eigen::Vector3d x = site.SiteFromWgs84({d, 0.0, 0.0});
    const double r = d * M_PI / 180.0;
    EXPECT_NEAR(x.x(), kA * std::sin(r), 1e-6) << d;
    EXPECT_NEAR(x.y(), 0.0, 1e-6) << d;
    EXPECT_NEAR(x.z(), kA * (std::cos(r) - 1.0), 1e-6) << d;
    const Eigen::Vector3d back = site.Wgs84FromSite(x);
    EXPECT_NEAR(back.x(), d, 1e-11);
    EXPECT_NEAR(back.y(), 0.0, 1e-11);
    EXPECT_NEAR(back.z(), 0.0, 1e-6);
  }
  // The north pole: b north of the centre, a below the origin.
  const Eigen::Vector3d pole = site.SiteFromWgs84({0.0, 90.0, 0.0});
  EXPECT_NEAR(pole.x(), 0.0, 1e-6);
  EXPECT_NEAR(pole.y(), kB, 1e-6);
  EXPECT_NEAR(pole.z(), -kA, 1e-6);
  // 100 m above the origin is 100 m up.
  EXPECT_NEAR(site.SiteFromWgs84({0.0, 0.0, 100.0}).z(), 100.0, 1e-9);
}

TEST(SiteCrs, ShiftedCrsSubtractsTheOrigin) {
  SiteCrsOptions o;
  o.crs = "EPSG:6677";
  o.origin = Eigen::Vector3d(-21000.0, -11000.0, 120.0);
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs site(o);
  const Eigen::Vector3d x = site.SiteFromCrs({-20990.0, -10980.0, 125.0});
  EXPECT_NEAR((x - Eigen::Vector3d(10.0, 20.0, 5.0)).norm(), 0.0, 1e-9);
  // Zone IX's origin (36 N, 139 deg 50' E) is (0, 0) of the CRS.
  const Eigen::Vector3d origin_of_zone = site.Wgs84FromSite(-o.origin);
  EXPECT_NEAR(origin_of_zone.x(), 139.0 + 50.0 / 60.0, 1e-10);
  EXPECT_NEAR(origin_of_zone.y(), 36.0, 1e-10);
  EXPECT_FALSE(site.CrsWkt().empty());
}

TEST(SiteCrs, BadCrsAndOriginAreNamed) {
  SiteCrsOptions o;
  o.crs = "EPSG:999999";
  try {
    SiteCrs site(o);
    FAIL() << "an unknown CRS was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("EPSG:999999"), std::string::npos) << e.what();
  }
  o.crs = "";
  EXPECT_THROW(SiteCrs{o}, InvalidArgument);
  o.crs = "EPSG:4979";
  o.origin = Eigen::Vector3d(0.0, NAN, 0.0);
  EXPECT_THROW(SiteCrs{o}, InvalidArgument);
  EXPECT_THROW(SiteCrs::LocalEnuAtWgs84(95.0, 0.0, 0.0), InvalidArgument);
  EXPECT_THROW(ParseSiteFrame("enu"), InvalidArgument);
  EXPECT_EQ(ParseSiteFrame("shifted_crs"), SiteCrsOptions::Frame::kShiftedCrs);
}

// The map CRS of a local_enu site (the outputs' EPSG code): the UTM zone of
// its origin. At 35 N, 139 E (zone 54, central meridian 141 E, 2 deg east)
// the hand values of transverse Mercator to first order: meridian convergence
// gamma = dlon sin(lat) = 1.1472 deg (true north points west of grid north
// there, so a step north in ENU goes east in UTM), and scale 0.9996 (1 +
// (dlon cos(lat))^2 / 2) = 1.0000087, times R / (R + h) = 0.9999843 for ENU
// metres 100 m above the ellipsoid (R = 6 371 km): 0.999993.
TEST(SiteCrs, LocalEnuSiteMapsToTheUtmZoneOfItsOrigin) {
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(35.0, 139.0, 100.0);
  EXPECT_EQ(site.MapCrs(), "EPSG:32654");
  EXPECT_EQ(site.MapEpsg(), 32654);
  const Eigen::Vector3d o = site.MapFromSite(Eigen::Vector3d::Zero());
  EXPECT_NEAR(o.z(), 100.0, 1e-6);  // WGS 84 ellipsoidal height
  const Eigen::Vector3d north = site.MapFromSite({0.0, 100.0, 0.0}) - o;
  const Eigen::Vector3d east = site.MapFromSite({100.0, 0.0, 0.0}) - o;
  const double gamma = std::atan2(north.x(), north.y()) * 180.0 / M_PI;
  EXPECT_NEAR(gamma, 2.0 * std::sin(35.0 * M_PI / 180.0), 0.002);
  const double scale =
      0.9996 * (1.0 + std::pow(2.0 * M_PI / 180.0 * std::cos(35.0 * M_PI / 180.0), 2) / 2.0) *
      6371000.0 / (6371000.0 + 100.0);
  EXPECT_NEAR(east.head<2>().norm() / 100.0, scale, 3e-6);
  EXPECT_NEAR(north.head<2>().norm() / 100.0, scale, 3e-6);
  // Back to the site exactly (PROJ both ways).
  for (const Eigen::Vector3d x :
       {Eigen::Vector3d(250.0, -120.0, 35.0), Eigen::Vector3d(-400.0, 300.0, -20.0)})
    EXPECT_LT((site.SiteFromMap(site.MapFromSite(x)) - x).norm(), 1e-6);
  // South of the equator: zone 34 south (Cape Town, 33.9 S, 18.4 E).
  EXPECT_EQ(SiteCrs::LocalEnuAtWgs84(-33.9, 18.4, 0.0).MapCrs(), "EPSG:32734");
  // A shifted CRS is its own map CRS: site plus the origin.
  SiteCrsOptions shifted;
  shifted.crs = "EPSG:6677";
  shifted.origin = Eigen::Vector3d(-21000.0, -11000.0, 120.0);
  shifted.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs zone_ix(shifted);
  EXPECT_EQ(zone_ix.MapEpsg(), 6677);
  EXPECT_LT(
      (zone_ix.MapFromSite({1.0, 2.0, 3.0}) - Eigen::Vector3d(-20999.0, -10998.0, 123.0)).norm(),
      1e-9);
}

}  // namespace
}  // namespace slope_monitor
