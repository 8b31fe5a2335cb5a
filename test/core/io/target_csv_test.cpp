// Target lists given in UTM zone 54N (EPSG:32654) and in JGD2011 plane
// rectangular zone IX (EPSG:6677) turn into `site` and back within 1 mm.
//
// The reference coordinates are computed here independently of PROJ:
//  * grid coordinates by Krüger's transverse Mercator series to 4th order in
//    the third flattening n (C. F. F. Karney, "Transverse Mercator with an
//    accuracy of a few nanometers", J. Geodesy 85 (2011), eqs. 7-11 and 35;
//    the 4th-order truncation is good to well under 0.1 mm within a few
//    hundred km of the central meridian). The series is checked below on the
//    hand-checkable points: zone IX's origin (36 N, 139 deg 50' E) is
//    (0, 0) and UTM 54N's (0 N, 141 E) is (500000, 0).
//    Zone IX: GRS80, lat_0 36, lon_0 139 deg 50', k0 0.9999, no false
//    origin (GSI, Japanese plane rectangular coordinate systems, MLIT notice
//    No. 9 of 2002). UTM 54N: WGS 84, lon_0 141, k0 0.9996, E0 500 km.
//  * site coordinates (local east-north-up at the origin) from the WGS 84
//    ECEF formula and the ENU rotation written out below.
// JGD2011 latitudes/longitudes are used as WGS 84 ones (EPSG's
// transformation JGD2011 -> WGS 84 is the null transformation), heights are
// ellipsoidal and pass through the 2-D grids unchanged.
#include "slope_monitor/core/io/target_csv.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

constexpr double kDeg = M_PI / 180.0;

struct TransverseMercator {
  double a, f, k0, lon0_deg, lat0_deg, false_easting;
};
const TransverseMercator kUtm54{6378137.0, 1.0 / 298.257223563, 0.9996, 141.0, 0.0, 500000.0};
const TransverseMercator kZoneIX{6378137.0, 1.0 / 298.257222101, 0.9999, 139.0 + 50.0 / 60.0, 36.0,
                                 0.0};

// Krüger's series: (xi, eta) on the sphere of radius A for latitude `lat`,
// longitude difference `dlon` [rad].
Eigen::Vector2d XiEta(const TransverseMercator& tm, double lat, double dlon) {
  const double f = tm.f, n = f / (2.0 - f), e = std::sqrt(f * (2.0 - f));
  const double n2 = n * n, n3 = n2 * n, n4 = n3 * n;
  const double alpha[4] = {n / 2 - 2 * n2 / 3 + 5 * n3 / 16 + 41 * n4 / 180,
                           13 * n2 / 48 - 3 * n3 / 5 + 557 * n4 / 1440,
                           61 * n3 / 240 - 103 * n4 / 140, 49561 * n4 / 161280};
  const double s = std::sin(lat);
  const double t =
      std::sinh(std::atanh(s) - e * std::atanh(e * s));  // tan of the conformal latitude
  const double xi1 = std::atan2(t, std::cos(dlon));
  const double eta1 = std::atanh(std::sin(dlon) / std::sqrt(1.0 + t * t));
  Eigen::Vector2d xe(xi1, eta1);
  for (int j = 1; j <= 4; ++j) {
    xe.x() += alpha[j - 1] * std::sin(2 * j * xi1) * std::cosh(2 * j * eta1);
    xe.y() += alpha[j - 1] * std::cos(2 * j * xi1) * std::sinh(2 * j * eta1);
  }
  return xe;
}

// (lon, lat [deg], h) -> (easting, northing, h).
Eigen::Vector3d GridFromGeodetic(const TransverseMercator& tm, const Eigen::Vector3d& llh) {
  const double n = tm.f / (2.0 - tm.f);
  const double A = tm.a / (1.0 + n) * (1.0 + n * n / 4.0 + n * n * n * n / 64.0);
  const Eigen::Vector2d p = XiEta(tm, llh.y() * kDeg, (llh.x() - tm.lon0_deg) * kDeg);
  const Eigen::Vector2d p0 = XiEta(tm, tm.lat0_deg * kDeg, 0.0);
  return Eigen::Vector3d(tm.false_easting + tm.k0 * A * p.y(), tm.k0 * A * (p.x() - p0.x()),
                         llh.z());
}

Eigen::Vector3d Ecef(const Eigen::Vector3d& llh) {
  const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2.0 - f);
  const double lat = llh.y() * kDeg, lon = llh.x() * kDeg, s = std::sin(lat);
  const double nu = a / std::sqrt(1.0 - e2 * s * s);
  return Eigen::Vector3d((nu + llh.z()) * std::cos(lat) * std::cos(lon),
                         (nu + llh.z()) * std::cos(lat) * std::sin(lon),
                         (nu * (1.0 - e2) + llh.z()) * s);
}

// Local east-north-up coordinates of `llh` at `origin` (both lon, lat, h).
Eigen::Vector3d Enu(const Eigen::Vector3d& origin, const Eigen::Vector3d& llh) {
  const double lat = origin.y() * kDeg, lon = origin.x() * kDeg;
  Eigen::Matrix3d r;
  r << -std::sin(lon), std::cos(lon), 0.0, -std::sin(lat) * std::cos(lon),
      -std::sin(lat) * std::sin(lon), std::cos(lat), std::cos(lat) * std::cos(lon),
      std::cos(lat) * std::sin(lon), std::sin(lat);
  return r * (Ecef(llh) - Ecef(origin));
}

// A slope in Gunma (zone IX, UTM 54): origin and 12 points within ~1 km.
const Eigen::Vector3d kOrigin(139.05, 36.40, 600.0);
std::vector<Eigen::Vector3d> SurveyedLlh() {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 12; ++i) {
    points.emplace_back(139.05 + 0.004 * (i % 4 - 1.5), 36.40 + 0.003 * (i / 4 - 1.0),
                        550.0 + 13.0 * i);
  }
  return points;
}

std::string Csv(const std::string& crs, const std::vector<Eigen::Vector3d>& xyz) {
  std::string text = "# crs: " + crs + "\nid,role,x,y,z,sigma_h,sigma_v\n";
  char line[200];
  for (size_t i = 0; i < xyz.size(); ++i) {
    std::snprintf(line, sizeof(line), "tag36h11/%zu,%s,%.9f,%.9f,%.4f,0.01,0.02\n", i,
                  i < 8 ? "control" : "check", xyz[i].x(), xyz[i].y(), xyz[i].z());
    text += line;
  }
  return text;
}

TEST(TargetCsv, ReferenceSeriesGivesTheHandCheckableGridOrigins) {
  const Eigen::Vector3d ix = GridFromGeodetic(kZoneIX, {139.0 + 50.0 / 60.0, 36.0, 0.0});
  EXPECT_NEAR(ix.x(), 0.0, 1e-9);
  EXPECT_NEAR(ix.y(), 0.0, 1e-9);
  const Eigen::Vector3d utm = GridFromGeodetic(kUtm54, {141.0, 0.0, 0.0});
  EXPECT_NEAR(utm.x(), 500000.0, 1e-9);
  EXPECT_NEAR(utm.y(), 0.0, 1e-9);
}

// The site is defined in JGD2011 zone IX (local ENU at its origin); one list
// comes in zone IX, one in UTM 54N, one in WGS 84.
TEST(TargetCsv, UtmAndJgd2011ZoneIXListsToSiteAndBackWithin1mm) {
  SiteCrsOptions o;
  o.crs = "EPSG:6677";
  o.origin = GridFromGeodetic(kZoneIX, kOrigin);
  const SiteCrs site(o);
  const std::vector<Eigen::Vector3d> llh = SurveyedLlh();
  struct List {
    std::string crs;
    const TransverseMercator* tm;
  };
  for (const List& list :
       {List{"EPSG:6677", &kZoneIX}, List{"EPSG:32654", &kUtm54}, List{"WGS 84", nullptr}}) {
    std::vector<Eigen::Vector3d> given;
    for (const Eigen::Vector3d& p : llh)
      given.push_back(list.tm ? GridFromGeodetic(*list.tm, p) : p);
    const std::vector<SurveyedPoint> points =
        ParseTargetCsv(Csv(list.crs, given), list.crs + ".csv", site);
    ASSERT_EQ(points.size(), llh.size());
    double worst_site = 0.0, worst_back = 0.0;
    for (size_t i = 0; i < llh.size(); ++i) {
      const Eigen::Vector3d truth = Enu(kOrigin, llh[i]);
      EXPECT_LT((points[i].position_in_site - truth).norm(), 1e-3)
          << list.crs << " point " << i << ": site " << points[i].position_in_site.transpose()
          << " reference " << truth.transpose();
      const Eigen::Vector3d back = ListCrsFromSite(site, list.crs, points[i].position_in_site);
      worst_site = std::max(worst_site, (points[i].position_in_site - truth).norm());
      if (list.tm) worst_back = std::max(worst_back, (back - given[i]).norm());
      if (list.tm) {
        EXPECT_LT((back - given[i]).norm(), 1e-3)
            << list.crs << " point " << i << " back " << back.transpose();
      } else {
        EXPECT_LT((back.head<2>() - given[i].head<2>()).norm(), 1e-10) << "WGS 84 point " << i;
        EXPECT_NEAR(back.z(), given[i].z(), 1e-3);
      }
    }
    std::printf("%s: worst |site - reference| %.6f mm, worst |back - given| %.6f mm\n",
                list.crs.c_str(), worst_site * 1e3, worst_back * 1e3);
    EXPECT_EQ(points[0].family, "tag36h11");
    EXPECT_EQ(points[8].role, TargetRole::kCheck);
    EXPECT_DOUBLE_EQ(points[3].sigma.y(), 0.02);
  }
}

TEST(TargetCsv, SiteListsAndShiftedCrsSites) {
  SiteCrsOptions o;
  o.crs = "EPSG:6677";
  o.origin = Eigen::Vector3d(-70000.0, 44000.0, 0.0);
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs site(o);
  const auto points = ParseTargetCsv(
      "# crs: "
      "EPSG:6677\nid,role,x,y,z,sigma_h,sigma_v\n\n5,control,-69990.5,44020.25,612.5,0.01,0.01\n",
      "a.csv", site, "circle");
  ASSERT_EQ(points.size(), 1u);
  EXPECT_EQ(points[0].family, "circle");
  EXPECT_EQ(points[0].id, 5);
  EXPECT_LT((points[0].position_in_site - Eigen::Vector3d(9.5, 20.25, 612.5)).norm(), 1e-9);
  const auto local = ParseTargetCsv(
      "# crs: site\nid,role,x,y,z,sigma_h,sigma_v\n1,monitoring,1,2,3,0.1,0.2\n", "b.csv", site);
  EXPECT_LT((local[0].position_in_site - Eigen::Vector3d(1, 2, 3)).norm(), 1e-12);

  TargetList list;
  ApplySurveyedPoints(points, 0.3, &list);
  ASSERT_NE(list.Find("circle", 5), nullptr);
  EXPECT_LT((*list.Find("circle", 5)->position - Eigen::Vector3d(9.5, 20.25, 612.5)).norm(), 1e-9);
}

TEST(TargetCsv, BadInputNamesFileLineAndColumn) {
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(36.4, 139.05, 600.0);
  auto message = [&](const std::string& text) {
    try {
      ParseTargetCsv(text, "crew.csv", site);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string head = "# crs: WGS 84\nid,role,x,y,z,sigma_h,sigma_v\n";
  EXPECT_NE(message("id,role,x,y,z,sigma_h,sigma_v\n")
                .find("crew.csv:1: the first line must name the CRS"),
            std::string::npos);
  EXPECT_NE(message("# crs: WGS 84\nid,x,y,z\n").find("crew.csv:2:"), std::string::npos);
  EXPECT_NE(
      message(head + "1,control,139.05,36.4,abc,0.01,0.01\n").find("crew.csv:3: column z 'abc'"),
      std::string::npos);
  EXPECT_NE(message(head + "1,boss,139.05,36.4,1,0.01,0.01\n").find("crew.csv:3: column role"),
            std::string::npos);
  EXPECT_NE(message(head + "1,control,139.05,36.4,1,0.01\n").find("6 columns"), std::string::npos);
  EXPECT_NE(
      message(head + "1,control,139.05,36.4,1,0,0.01\n").find("sigma_h and sigma_v must be > 0"),
      std::string::npos);
  EXPECT_NE(message(head + "1,control,139.05,36.4,1,0.1,0.1\n1,check,139.05,36.4,1,0.1,0.1\n")
                .find("crew.csv:4: target tag36h11/1 already on line 3"),
            std::string::npos);
  EXPECT_NE(message("# crs: EPSG:999999\nid,role,x,y,z,sigma_h,sigma_v\n1,control,1,2,3,0.1,0.1\n")
                .find("crew.csv:1: crs 'EPSG:999999' of the list"),
            std::string::npos);
  EXPECT_THROW(ReadTargetCsv("/nonexistent/crew.csv", site), ConfigError);
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
